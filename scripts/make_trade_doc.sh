#!/usr/bin/env bash
# Runs `obscura compare` on the bundled scene and on every scene of
# ../shared/scenes/ (skipping, with a message, those that are absent), then
# writes docs/trade.md from the results of two of them (the bundled scene and
# the classic Cornell box), with their plots, contact sheets and heat maps
# under docs/trade/. Nothing in docs/trade.md's tables is typed by hand.
#
#   scripts/make_trade_doc.sh            # all scenes, then docs/trade.md
#   scripts/make_trade_doc.sh doc        # only the two documented scenes
#   scripts/make_trade_doc.sh lit        # only "Under an environment map" (below),
#                                        # rewritten in place between its markers
#
# Three compare runs per scene, all against the same gi reference unless said:
#   OUT/NAME       the ray-traced configs at SPP;
#   OUT/NAME-ss    the screen-space configs (`vo`, `ssat`, their traced twins)
#                  and their ray-traced targets at SS_SPP: for them spp counts
#                  G-buffer layers of `count` = 16 estimator samples each, so
#                  they converge in fewer and 256 would only cost time;
#   OUT/NAME-vs-ao-RR  the screen-space obscurance configs at SS_CHECK_SPP
#                  against `ao:distance=R` itself (AO_REFERENCE_SPP spp) - the
#                  quantity ssat converges to when the depth buffer holds
#                  every occluder - so their blind spots show apart from how
#                  far obscurance is from GI; at the scene's R and at a
#                  second, smaller one, to see how the blind spots grow with R.
# Rerunning keeps every finished cell (compare resumes); delete OUT to start over.
#
# Environment: BUILD_DIR (default build), OUT (default out/trade),
# RES (320x180), SPP (4,16,64,256), SS_SPP (1,4,16,64), SS_CHECK_SPP (16),
# SEEDS (2), REFERENCE_SPP (2048), AO_REFERENCE_SPP (2048),
# DOC=0 to only run the comparisons (e.g. a quick check at small settings).
#
# "Under an environment map" (LIT=0 skips it): `obscura sky` writes three maps
# into OUT/lit/maps - a constant sky of 1 (`gradient a=1 b=0`), the CIE
# overcast sky and a sun-and-sky (`sunsky`, sun at LIT_ELEVATION (30) degrees,
# azimuth LIT_AZIMUTH (40), default turbidity and sun) - and the bundled scene
# and the viking room are compared under each (OUT/lit/NAME-MAP) with
# `--environment`, so that every column is of shaded.*, relative to the mean
# (docs/compare.md "Under an environment map"); the constant map is the uniform
# sky measured the same way. Then the bundled scene's Figure 9 of the ambient
# transfer paper (Umenhoffer et al. section 6) from the sun-and-sky run's
# passes, at one exposure for all: LIT_EXPOSURE, or else the one that maps the
# reference's mean radiance to LIT_MIDGREY (0.18). Its settings: LIT_RES (RES),
# LIT_SPP (4,16,64,256), LIT_SEEDS (1), LIT_REFERENCE_SPP (1024).
# The maps are written anew each run (a second, same content: compare keys its
# reference cache by the map's content, so an unchanged map renders nothing).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
build="${BUILD_DIR:-build}"
out="${OUT:-out/trade}"
res="${RES:-320x180}"
spp="${SPP:-4,16,64,256}"
ss_spp="${SS_SPP:-1,4,16,64}"
ss_check_spp="${SS_CHECK_SPP:-16}"
seeds="${SEEDS:-2}"
refspp="${REFERENCE_SPP:-2048}"
aorefspp="${AO_REFERENCE_SPP:-2048}"
shared="$root/../shared/scenes"
mode="${1:-}"
lit="${LIT:-1}"
lit_res="${LIT_RES:-$res}"
lit_spp="${LIT_SPP:-4,16,64,256}"
lit_seeds="${LIT_SEEDS:-1}"
lit_refspp="${LIT_REFERENCE_SPP:-1024}"
lit_elevation="${LIT_ELEVATION:-30}"
lit_azimuth="${LIT_AZIMUTH:-40}"
start=$SECONDS

if [[ ! -x "$build/obscura" ]]; then
  cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
  cmake --build "$build" --target obscura
fi

# The ray-traced configs every scene is measured with: the approximations from
# the cheapest up, then one-bounce GI and full GI at the same spp.
# Then the time-to-error axis (docs/compare.md "Compare"): adaptive sampling to a
# standard error of 0.02 per pixel (spp = the most a pixel takes), the
# denoiser on the fixed-spp pass, and both; their time includes the denoiser.
configs=(-c ao -c transfer -c transfer:depth=1 -c transfer:depth=2 -c multibounce
  -c multibounce:mapping=improved -c gi:max-depth=1 -c gi
  -c ao:target=0.02 -c ao:denoise=on -c ao:target=0.02,denoise=on
  -c transfer:target=0.02 -c transfer:denoise=on -c transfer:target=0.02,denoise=on)

# The screen-space configs at radius R (vo's `radius`, ssat's `distance`).
# They cannot take R = inf as `ao` does, so each scene names its own R (the
# last field below) and they are measured beside their ray-traced targets at
# that R: `ao:distance=R` (what ssat's obscurance converges to) and
# `transfer:distance=R` (ssat albedo=true's ray-traced counterpart).
ss_configs() {
  local r=$1
  ss_targets=(-c "ao:distance=$r" -c "transfer:distance=$r")
  ss_obscurance=(-c "vo:samples=point,radius=$r" -c "vo:samples=line,radius=$r" -c "vo:samples=area,radius=$r"
    -c "vo:samples=point,radius=$r,depth=traced" -c "vo:samples=line,radius=$r,depth=traced"
    -c "ssat:distance=$r" -c "ssat:distance=$r,interleave=off" -c "ssat:distance=$r,silhouette=false"
    -c "ssat:distance=$r,depth=traced")
  ss_transfer=(-c "ssat:distance=$r,albedo=true")
}

# name|path (relative to the repository or to ../shared/scenes)|R|smaller R.
# R is about the size of the space the occluders enclose, so that
# `ao:distance=R` is about as far from GI as `ao` (R = inf) is: the bundled
# scene's walls are 2.4 high and 8 wide, and its objects stand a metre or two
# from them (R = 2); the Cornell box is a closed 5.5 cube lit through its open
# front, so anything shorter than the box leaves the floor far brighter than
# GI (R = 5). The smaller R (contact shadows only) is measured against
# `ao:distance` alone.
documented=("default|scenes/default.gltf|2|0.5" "cornell_box_classic|$shared/cornell_box_classic/cornell-box.gltf|5|1")
others=("cornell_box_suzanne|$shared/cornell_box_suzanne/cornell-box.glb|1.8|0.4"
  "damaged_helmet|$shared/damaged_helmet/DamagedHelmet.gltf|0.5|0.1"
  "suzanne|$shared/suzanne/Suzanne.gltf|0.5|0.1"
  "viking_room|$shared/viking_room/viking_room.glb|0.4|0.1")
scenes=("${documented[@]}")
if [[ "${1:-}" != doc ]]; then scenes+=("${others[@]}"); fi

# "Under an environment map": the ray-traced approximations from the cheapest up
# (`obscurance` at its defaults, step falloff and R = inf, is `ao` bit for bit:
# its row is the check, and Figure 9 names it O), directional occlusion (the
# environment's exact direct light), then one-bounce and full GI.
lit_configs=(-c ao -c obscurance -c transfer -c transfer:depth=1 -c multibounce -c dirocc
  -c gi:max-depth=1 -c gi)
lit_maps=(uniform overcast sunsky)
lit_scenes=("default|scenes/default.gltf" "viking_room|$shared/viking_room/viking_room.glb")
lit_runs() {
  local maps="$out/lit/maps" name path map
  mkdir -p "$maps"
  "$build/obscura" sky gradient -p a=1 -p b=0 --res 64x32 -o "$maps/uniform.exr"
  "$build/obscura" sky overcast -o "$maps/overcast.exr"
  "$build/obscura" sky sunsky -p "elevation=$lit_elevation" -p "azimuth=$lit_azimuth" -o "$maps/sunsky.exr"
  for entry in "${lit_scenes[@]}"; do
    IFS='|' read -r name path <<<"$entry"
    if [[ ! -f "$path" ]]; then
      echo "== skipping $name under the maps: $path is absent"
      continue
    fi
    for map in "${lit_maps[@]}"; do
      echo "== $name under $map"
      local t0=$SECONDS
      "$build/obscura" compare "$path" -o "$out/lit/$name-$map" --res "$lit_res" --spp "$lit_spp" \
        --seeds "$lit_seeds" --reference-spp "$lit_refspp" --environment "$maps/$map.exr" "${lit_configs[@]}"
      echo "== $name under $map took $((SECONDS - t0)) s"
    done
  done
}

mkdir -p "$out"
if [[ "$mode" == lit ]]; then scenes=(); fi
for entry in "${scenes[@]}"; do
  IFS='|' read -r name path r r_small <<<"$entry"
  if [[ ! -f "$path" ]]; then
    echo "== skipping $name: $path is absent"
    continue
  fi
  ss_configs "$r"
  echo "== $name (screen-space R = $r)"
  "$build/obscura" compare "$path" -o "$out/$name" --res "$res" --spp "$spp" --seeds "$seeds" \
    --reference-spp "$refspp" "${configs[@]}"
  # The same gi reference: compare keys its cache by scene, view, sky, spp and
  # seed, so a copy is found and not rendered again.
  mkdir -p "$out/$name-ss/cache"
  cp -p "$out/$name"/cache/reference-*.exr "$out/$name-ss/cache/"
  "$build/obscura" compare "$path" -o "$out/$name-ss" --res "$res" --spp "$ss_spp" --seeds "$seeds" \
    --reference-spp "$refspp" "${ss_targets[@]}" "${ss_obscurance[@]}" "${ss_transfer[@]}"
  for check_r in "$r" "$r_small"; do
    ss_configs "$check_r"
    aoref="$out/$name-ao-reference-R$check_r-$res-$aorefspp.exr"
    if [[ ! -f "$aoref" ]]; then
      "$build/obscura" render "$path" -o "$aoref" -i ao -p "distance=$check_r" --spp "$aorefspp" --res "$res" --quiet
    fi
    "$build/obscura" compare "$path" -o "$out/$name-vs-ao-R$check_r" --res "$res" --spp "$ss_check_spp" \
      --reference "$aoref" "${ss_obscurance[@]}"
  done
done
if [[ "$lit" != 0 ]]; then lit_runs; fi
echo "== comparisons took $((SECONDS - start)) s"

if [[ "${DOC:-1}" == 0 ]]; then exit 0; fi

# The tables of one documented scene from compare's results.json files:
# every cell of the two gi-referenced runs in one table, the fastest cell
# reaching each RMSE target and the Pareto front over both runs, then the
# screen-space configs against ao:distance=R.
tables() {
  python3 - "$@" <<'PY'
import json, sys

traced, ss, r, aorefspp = json.load(open(sys.argv[1])), json.load(open(sys.argv[2])), sys.argv[3], sys.argv[4]
checks = [(a.split("=", 1)[0], json.load(open(a.split("=", 1)[1]))) for a in sys.argv[5:]]  # R=results.json
cells = traced["cells"] + ss["cells"]
num = lambda v: "%.3g" % v
screen_space = lambda c: c["integrator"] in ("vo", "ssat")

# mean spp: what a target= config's pixels took on average (spp is their
# most); denoise s: the filter's share of the time (time includes it).
# With --seeds >= 2 compare gives each time and RMSE an interval (docs/compare.md "Uncertainty").
# FLIP, HDR-FLIP: the perceptual errors (docs/compare.md "FLIP").
def withci(c, key, ci):
    return num(c[key]) + (" [%s, %s]" % (num(c[ci][0]), num(c[ci][1])) if ci in c else "")
print("| config | spp | mean spp | time s [min, max] | denoise s | Mrays | RMSE [95% CI] | relMSE | MAE | p99 | FLIP | HDR-FLIP | bias² | variance |")
print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
for c in cells:
    bv = (num(c["bias2"]), num(c["variance"])) if "bias2" in c else ("", "")
    flip = (num(c["flip"]), num(c["flipHdr"])) if "flip" in c else ("", "")
    print("| `%s` | %d | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s |" % (
        c["config"], c["spp"], num(c.get("meanSpp", c["spp"])), withci(c, "seconds", "secondsInterval"),
        num(c["denoiseSeconds"]) if c.get("denoise") else "", num(c["rays"] * 1e-6), withci(c, "rmse", "rmseInterval"),
        num(c["relMse"]), num(c["mae"]), num(c["p99"]), *flip, *bv))
print()
noise = traced["reference"].get("noiseRmse")
if noise is not None:
    print("Reference noise (RMSE of the gi reference itself): %s. Screen-space R = %s." % (num(noise), r))
    print()

# The verdict over both runs, as compare makes it within one (docs/compare.md
# "Uncertainty"): the runner-up is the fastest other config reaching the
# target, and Welch's t-test of their per-seed times says whether it is
# distinguishable from the winner at 95% or ties. The t quantile here is the
# density integrated numerically (Simpson), not compare's incomplete beta.
import math
def t_cdf(x, dof):
    if x < 0:
        return 1 - t_cdf(-x, dof)
    c = math.exp(math.lgamma((dof + 1) / 2) - math.lgamma(dof / 2)) / math.sqrt(dof * math.pi)
    f = lambda u: c * (1 + u * u / dof) ** (-(dof + 1) / 2)
    n = 2000
    h = x / n
    return 0.5 + h / 3 * sum((1 if i in (0, n) else 4 if i % 2 else 2) * f(i * h) for i in range(n + 1))
def t_quantile(p, dof):
    lo, hi = 0.0, 1.0
    while t_cdf(hi, dof) < p:
        hi *= 2
    for _ in range(60):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if t_cdf(mid, dof) < p else (lo, mid)
    return (lo + hi) / 2
def verdict(w, r):
    if r is None:
        return "no runner-up"
    a, b = w.get("seedSeconds", []), r.get("seedSeconds", [])
    name = "`%s` @ %d" % (r["config"], r["spp"])
    if len(a) < 2 or len(b) < 2:
        return "runner-up %s; one seed" % name
    mean = lambda x: sum(x) / len(x)
    var = lambda x: sum((v - mean(x)) ** 2 for v in x) / (len(x) - 1) / len(x)
    d, se2 = mean(b) - mean(a), var(a) + var(b)
    if se2 == 0:
        lo = hi = d
    else:
        dof = se2 ** 2 / (var(a) ** 2 / (len(a) - 1) + var(b) ** 2 / (len(b) - 1))
        half = t_quantile(0.975, dof) * math.sqrt(se2)
        lo, hi = d - half, d + half
    word = "distinguishable" if lo > 0 or hi < 0 else "tie"
    return "%s: runner-up %s, %s s slower (95%% CI %s to %s)" % (word, name, num(d), num(lo), num(hi))
print("| RMSE target | fastest cell reaching it | confidence (Welch's t-test of the runner-up's time, 95%) |")
print("|---:|---|---|")
def fastest(pool, t):
    ok = [c for c in pool if c["rmse"] <= t]
    if not ok:
        return "not reached", ""
    b = min(ok, key=lambda c: c["seconds"])
    others = [c for c in ok if c["config"] != b["config"]]
    r = min(others, key=lambda c: c["seconds"]) if others else None
    mean = " (mean %s)" % num(b["meanSpp"]) if "targetError" in b else ""
    return "`%s` @ %d spp%s, %s s" % (b["config"], b["spp"], mean, num(b["seconds"])), verdict(b, r)
for t in (x["rmse"] for x in traced["targets"]):
    print("| %s | %s | %s |" % ((num(t),) + fastest(cells, t)))
print()
b = min((c for c in cells if screen_space(c)), key=lambda c: c["rmse"])
print("Lowest RMSE of a screen-space (`vo`, `ssat`) cell: %s, `%s` @ %d spp, %s s." % (num(b["rmse"]), b["config"],
                                                                                   b["spp"], num(b["seconds"])))
print()

# A cell is on the front when no other cell is both faster and more accurate:
# in order of time (ties: lower RMSE first), each cell that beats the lowest
# RMSE seen so far.
front, best = [], float("inf")
for c in sorted(cells, key=lambda c: (c["seconds"], c["rmse"])):
    if c["rmse"] < best:
        front.append(c)
        best = c["rmse"]
print("Pareto front of both runs (%d of %d cells; each is faster than every cell more accurate than it):"
      % (len(front), len(cells)))
print()
print("| time s | config | spp | RMSE | kind |")
print("|---:|---|---:|---:|---|")
for c in front:
    kind = "screen-space" if screen_space(c) else "ray-traced"
    print("| %s | `%s` | %d | %s | %s |" % (num(c["seconds"]), c["config"], c["spp"], num(c["rmse"]), kind))
print()

print("The screen-space configs against `ao:distance=R` (a %s-spp render) instead of GI, at %d spp, one seed:"
      % (aorefspp, checks[0][1]["cells"][0]["spp"]))
print("their own error, what the depth buffer and the model miss of the obscurance they estimate, at the R above")
print("and at a smaller one (`vo` estimates volumetric obscurance, a ball's empty fraction, so its rows include")
print("that difference of definition).")
print()
print("| config | time s | RMSE | MAE | p99 |")
print("|---|---:|---:|---:|---:|")
for _, check in checks:
    for c in check["cells"]:
        print("| `%s` | %s | %s | %s | %s |" % (c["config"], num(c["seconds"]), num(c["rmse"]), num(c["mae"]),
                                               num(c["p99"])))
print()

# The traced twins: the same estimator with every depth read traced instead of
# read from the z-buffer, so the part of a config's MSE that goes when the
# twin replaces it is the depth buffer's (discretization, off-image points);
# the rest is the model's.
print("Model or depth buffer: each config beside its traced twin (MSE = RMSE², share = 1 − MSE_traced / MSE;")
print("negative where the two differ by less than their noise).")
print()
print("| config | against | spp | RMSE | RMSE traced | depth buffer's share of the MSE |")
print("|---|---|---:|---:|---:|---:|")
def twins(pool, against):
    last = {}
    for c in pool:  # each config's highest spp
        if c["spp"] >= last.get(c["config"], {"spp": -1})["spp"]:
            last[c["config"]] = c
    for name, c in last.items():
        t = last.get(name + ",depth=traced")
        if t:
            print("| `%s` | %s | %d | %s | %s | %s |" % (name, against, c["spp"], num(c["rmse"]), num(t["rmse"]),
                                                    num(1 - t["rmse"] ** 2 / c["rmse"] ** 2)))
twins(ss["cells"], "gi")
for check_r, check in checks:
    twins(check["cells"], "`ao:distance=%s`" % check_r)
print()

vs_ao = checks[0][1]
print("Heat maps of |e| at R = %s against `ao:distance=%s` (dark purple 0 to pale yellow %s and above; grey: not"
      " compared), left to right and down in the order of the table against `ao:distance=R` (its first %d rows):"
      % (r, r, num(vs_ao["heatmapScale"]), len(vs_ao["cells"])))
print()
PY
}

# "Under an environment map" of docs/trade.md, between its markers, from the
# OUT/lit runs: each config's RMSE (relative to the mean) at its highest spp
# under the three maps, the maps' previews, and Figure 9.
lit_begin='<!-- lit:begin (generated by scripts/make_trade_doc.sh lit) -->'
lit_end='<!-- lit:end -->'
lit_table() {
  python3 - "$@" <<'PY'
import json, os, re, subprocess, sys

maps = [("uniform", "uniform (constant 1)"), ("overcast", "overcast"), ("sunsky", "sun and sky")]
runs = {m: json.load(open(os.path.join(sys.argv[1] + "-" + m, "results.json"))) for m, _ in maps}
num = lambda v: "%.3g" % v
def last(run):  # each config's cell at its highest spp, in results.json's order
    out = {}
    for c in run["cells"]:
        if c["spp"] >= out.get(c["config"], {"spp": -1})["spp"]:
            out[c["config"]] = c
    return out
cells = {m: last(runs[m]) for m, _ in maps}
def mean(path):  # of R,G,B over the image (under a map a pass's R,G,B is its shaded.*)
    s = subprocess.run(["oiiotool", "--wildcardoff", "--stats", path], capture_output=True, text=True).stdout
    return sum(map(float, re.search(r"Stats Avg: (\S+) (\S+) (\S+)", s).groups())) / 3
def shift(m, c):  # the cell's mean radiance against the reference's, in percent
    d = os.path.join(sys.argv[1] + "-" + m)
    return "%+.0f %%" % (100 * (mean(os.path.join(d, c["pass"])) / mean(runs[m]["reference"]["path"]) - 1))
print("| config | spp | RMSE " + " | RMSE ".join(t for _, t in maps) + " | sun / uniform | mean vs ref. "
      + " | mean vs ref. ".join(t for _, t in maps) + " | time s (sun) |")
print("|---|---:|" + "---:|" * len(maps) + "---:|" + "---:|" * len(maps) + "---:|")
for name, c in cells["uniform"].items():
    row = [cells[m][name]["rmse"] for m, _ in maps]
    print("| `%s` | %d | %s | %s | %s | %s |" % (name, c["spp"], " | ".join(num(v) for v in row), num(row[2] / row[0]),
          " | ".join(shift(m, cells[m][name]) for m, _ in maps), num(cells["sunsky"][name]["seconds"])))
print("| reference noise | %s | %s | | | | | |" % (sys.argv[2], " | ".join(
    num(runs[m]["reference"]["noiseRmse"]) for m, _ in maps)))
print()
means = []
for m, t in maps:
    means.append("%s %s" % (t, num(float(re.search(r"mean radiance ([0-9.eE+-]+)", runs[m]["lighting"]).group(1)))))
print("The unit of each column, the reference's mean radiance: %s." % ", ".join(means))
print()
PY
}
lit_section() {
  local run="$out/lit/default-sunsky" maps="$out/lit/maps" spp_max="${lit_spp##*,}" exposure sname spath
  echo "$lit_begin"
  echo "## Under an environment map"
  echo
  cat <<EOF
What each approximation's error becomes when the sky stops being uniform. Generated by
\`scripts/make_trade_doc.sh lit\` ($(git rev-parse --short HEAD 2>/dev/null || echo unknown), $(date -u +%Y-%m-%d)):
\`obscura sky\` writes three maps - a constant sky of radiance 1 (\`gradient -p a=1 -p b=0\`),
the CIE overcast sky (\`overcast\`) and a clear sky with the sun at ${lit_elevation}° elevation,
azimuth ${lit_azimuth}° (\`sunsky -p elevation=$lit_elevation -p azimuth=$lit_azimuth\`, default
turbidity 3 and sun) - and each scene is compared under each with

    obscura compare SCENE -o OUT/lit/SCENE-MAP --environment MAP.exr --res $lit_res --spp $lit_spp \\
      --seeds $lit_seeds --reference-spp $lit_refspp $(printf '%s ' "${lit_configs[@]}" | sed 's/ $//')

(LIT_RES, LIT_SPP, LIT_SEEDS, LIT_REFERENCE_SPP: $lit_seeds seed per cell and a \`gi\` reference of
$lit_refspp spp under the same map - fewer than the sections above, so that the six runs take about
ten minutes - on $(nproc) threads of a machine other jobs share). With
\`--environment\` every cell is measured by its \`shaded.*\`, the radiance it puts on screen,
relative to the reference's mean radiance (docs/compare.md "Under an environment map"): RMSE 0.1 is
10 % of the mean. The constant map is the uniform sky measured the same way: there \`shaded.*\` =
albedo × W, so its column ranks the configs much as W does above, but it weighs each pixel by its
albedo and divides by the mean radiance. Each config at its highest spp; "sun / uniform" is how
many times its error grows under the sun; "mean vs ref." is the cell's mean radiance over the image
against the reference's (negative: too dark). \`obscurance\` at its defaults (step falloff, R = ∞) is
\`ao\` bit for bit, and \`dirocc\` is \`ao\` under a uniform sky: those rows are checks.

EOF
  for entry in "${lit_scenes[@]}"; do
    IFS='|' read -r sname spath <<<"$entry"
    echo "### $sname (\`$(basename "$spath")\`)"
    echo
    if [[ ! -f "$out/lit/$sname-sunsky/results.json" ]]; then
      echo "_Not run: $spath is absent._"
      echo
      continue
    fi
    lit_table "$out/lit/$sname" "$lit_refspp"
    cp "$out/lit/$sname-sunsky/error_vs_time.svg" "docs/trade/lit-$sname-sunsky-error_vs_time.svg"
    echo "![error versus time under the sun and sky](trade/lit-$sname-sunsky-error_vs_time.svg)"
    echo
  done
  # The maps (top row the zenith, docs/math.md §14.1), exposure 1, clipped;
  # without the maps' DateTime, so that an unchanged preview stays the same file.
  oiiotool "$maps/overcast.exr" --eraseattrib DateTime --resize:filter=box 256x128 --colorconvert linear sRGB -o docs/trade/lit-overcast.png
  oiiotool "$maps/sunsky.exr" --eraseattrib DateTime --resize:filter=box 256x128 --colorconvert linear sRGB -o docs/trade/lit-sunsky.png
  echo "The two maps (lat-long, the zenith at the top, exposure 1, clipped at 1), overcast and sun and sky:"
  echo
  echo "![overcast](trade/lit-overcast.png) ![sun and sky](trade/lit-sunsky.png)"
  echo
  # Figure 9: one exposure for every shaded image, the one that maps the
  # reference's mean radiance to LIT_MIDGREY (0.18) unless LIT_EXPOSURE is set.
  exposure="${LIT_EXPOSURE:-$(python3 -c 'import json, re, sys
r = json.load(open(sys.argv[1]))
print("%.4g" % (float(sys.argv[2]) / float(re.search(r"mean radiance ([0-9.eE+-]+)", r["lighting"]).group(1))))' \
    "$run/results.json" "${LIT_MIDGREY:-0.18}")}"
  lit_pass() {  # the pass of config $1 at its highest spp
    python3 -c 'import json, sys
r = json.load(open(sys.argv[1] + "/results.json"))
print(sys.argv[1] + "/" + max((c for c in r["cells"] if c["config"] == sys.argv[2]), key=lambda c: c["spp"])["pass"])' \
      "$run" "$1"
  }
  # Under a map compare's passes (and its reference) hold shaded.* as R,G,B
  # (docs/compare.md); W is transfer's own R,G,B, so that pass is rendered
  # again in full by `obscura render`, with the same seed (0) and settings.
  # --wildcardoff: a pass's name has an @, which oiiotool reads as a frame.
  local shaded=(--ch R,G,B --mulc "$exposure" --colorconvert linear sRGB) w="$out/lit/default-sunsky-transfer@$spp_max.exr"
  [[ -f "$w" ]] || "$build/obscura" render scenes/default.gltf -o "$w" -i transfer --environment "$maps/sunsky.exr" \
    --spp "$spp_max" --res "$lit_res" --seed 0 --quiet
  oiiotool --wildcardoff "$(lit_pass obscurance)" "${shaded[@]}" -o docs/trade/lit-fig9-obscurance.png
  oiiotool --wildcardoff "$(lit_pass transfer)" "${shaded[@]}" -o docs/trade/lit-fig9-transfer.png
  oiiotool --wildcardoff "$w" --ch R,G,B --colorconvert linear sRGB -o docs/trade/lit-fig9-W.png
  oiiotool --wildcardoff "$(lit_pass gi)" "${shaded[@]}" -o docs/trade/lit-fig9-gi.png
  oiiotool --wildcardoff "$(lit_pass dirocc)" "${shaded[@]}" -o docs/trade/lit-fig9-dirocc.png
  oiiotool --wildcardoff "$(python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))["reference"]["path"])' \
    "$run/results.json")" "${shaded[@]}" -o docs/trade/lit-fig9-reference.png
  cat <<EOF
### Figure 9 of the ambient-transfer paper, under the sun and sky

The paper's Figure 9 (Umenhoffer et al. §6) shows a scene's environment lighting modulated by its
obscurances O and by its ambient transfer W, and W alone: the top row here, for the bundled scene
under the sun and sky above. Each pass at $spp_max spp (one seed, the passes of the table's cells),
every shaded image at one exposure (× $exposure: the reference's mean radiance to ${LIT_MIDGREY:-0.18}; linear to sRGB, clipped at 1):

| | | |
|---|---|---|
| ![obscurance](trade/lit-fig9-obscurance.png) | ![transfer](trade/lit-fig9-transfer.png) | ![W](trade/lit-fig9-W.png) |
| the environment's light modulated by the obscurance O (\`obscurance\`'s shaded.*) | modulated by the ambient transfer W (\`transfer\`'s shaded.*) | W alone (\`transfer\`'s R,G,B from \`obscura render\` with the same seed and spp, unscaled) |
| ![gi](trade/lit-fig9-gi.png) | ![dirocc](trade/lit-fig9-dirocc.png) | ![reference](trade/lit-fig9-reference.png) |
| \`gi\`'s shaded.* | \`dirocc\`'s shaded.*: the map's direct light, the sun's shadow included | the \`gi\` reference ($lit_refspp spp) |

EOF
  if [[ -f docs/trade_lit_reading.md ]]; then cat docs/trade_lit_reading.md; fi
  echo "$lit_end"
}

# `lit`: only the section, in place between its markers (appended the first time).
if [[ "$mode" == lit ]]; then
  mkdir -p docs/trade
  section="$(lit_section)"
  SECTION="$section" python3 - "$lit_begin" "$lit_end" docs/trade.md <<'PY'
import os, sys
begin, end, path = sys.argv[1:4]
text, section = open(path).read(), os.environ["SECTION"] + "\n"
i, j = text.find(begin), text.find(end)
if i >= 0 and j > i:
    text = text[:i] + section + text[j + len(end):].lstrip("\n")
else:
    text = text.rstrip("\n") + "\n\n" + section
open(path, "w").write(text)
PY
  echo "== wrote the lit section of docs/trade.md ($((SECONDS - start)) s in all)"
  exit 0
fi
# Without LIT the section already in docs/trade.md is kept as it is.
old_lit="$(sed -n "/^<!-- lit:begin/,/^<!-- lit:end -->/p" docs/trade.md 2>/dev/null || true)"

# docs/trade.md from the two documented scenes.
mkdir -p docs/trade
{
  cat <<EOF
# The speed/accuracy trade, measured

Generated by \`scripts/make_trade_doc.sh\` with \`obscura compare\` ($(git rev-parse --short HEAD 2>/dev/null || echo unknown),
$(date -u +%Y-%m-%d)): resolution $res, $seeds seeds per cell, a \`gi\` reference of $refspp spp,
$(nproc) threads on a machine other jobs share. Errors are deterministic
(fixed seeds); times are not - on a loaded machine they move by up to 2× between runs, so cells whose times are
that close can swap places on the Pareto front.
Ray-traced configs at spp $spp; screen-space configs (\`vo\`, \`ssat\`: spp = G-buffer layers of
16 samples each, docs/integrators.md "Screen-space passes") and their ray-traced targets at the same R at spp $ss_spp.
Errors are of W against the reference (docs/compare.md "Compare"); bias² and variance split the MSE of one render.
\`target=0.02\` configs sample adaptively to a standard error of 0.02 per pixel (spp is then the most a pixel
takes, "mean spp" what they took); \`denoise=on\` configs are denoised, and their time includes the denoiser.

EOF
  for entry in "${documented[@]}"; do
    IFS='|' read -r name path r r_small <<<"$entry"
    [[ -f "$out/$name/results.json" ]] || { echo "_${name}: not run (scene absent)._"; echo; continue; }
    cp "$out/$name/error_vs_time.svg" "docs/trade/$name-error_vs_time.svg"
    cp "$out/$name/contact_sheet.png" "docs/trade/$name-contact_sheet.png"
    cp "$out/$name-ss/error_vs_time.svg" "docs/trade/$name-ss-error_vs_time.svg"
    cp "$out/$name-ss/contact_sheet.png" "docs/trade/$name-ss-contact_sheet.png"
    # The heat maps of the run against ao:distance=R, three to a row, in
    # results.json's order (compare names each by its config, see safeFileName).
    mapfile -t maps < <(python3 -c 'import json, re, sys
for c in json.load(open(sys.argv[1] + "/results.json"))["cells"]:
    print(sys.argv[1] + "/heatmaps/" + re.sub(r"[^A-Za-z0-9.=-]", "_", c["config"]) + ".png")' "$out/$name-vs-ao-R$r")
    oiiotool "${maps[@]}" --mosaic:pad=2 "3x$(((${#maps[@]} + 2) / 3))" -o "docs/trade/$name-vs-ao-heatmaps.png"
    echo "## $name (\`$(basename "$path")\`)"
    echo
    echo "![error versus time, ray-traced]($(printf 'trade/%s-error_vs_time.svg' "$name"))"
    echo "![error versus time, screen-space]($(printf 'trade/%s-ss-error_vs_time.svg' "$name"))"
    echo
    echo "Contact sheets (the gi reference, then each config at its highest spp, in the table's order):"
    echo
    echo "![contact sheet, ray-traced]($(printf 'trade/%s-contact_sheet.png' "$name"))"
    echo
    echo "![contact sheet, screen-space]($(printf 'trade/%s-ss-contact_sheet.png' "$name"))"
    echo
    tables "$out/$name/results.json" "$out/$name-ss/results.json" "$r" "$aorefspp" \
      "$r=$out/$name-vs-ao-R$r/results.json" "$r_small=$out/$name-vs-ao-R$r_small/results.json"
    echo "![heat maps against ao:distance=R]($(printf 'trade/%s-vs-ao-heatmaps.png' "$name"))"
    echo
  done
  cat docs/trade_reading.md
  if [[ "$lit" != 0 ]]; then
    echo
    lit_section
  elif [[ -n "$old_lit" ]]; then
    echo
    printf '%s\n' "$old_lit"
  fi
} >docs/trade.md
echo "== wrote docs/trade.md ($((SECONDS - start)) s in all)"
