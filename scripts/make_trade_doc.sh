#!/usr/bin/env bash
# Runs `obscura compare` on the bundled scene and on every scene of
# ../shared/scenes/ (skipping, with a message, those that are absent), then
# writes docs/trade.md from the results of two of them (the bundled scene and
# the classic Cornell box), with their plots, contact sheets and heat maps
# under docs/trade/. Nothing in docs/trade.md's tables is typed by hand.
#
#   scripts/make_trade_doc.sh            # all scenes, then docs/trade.md
#   scripts/make_trade_doc.sh doc        # only the two documented scenes
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

mkdir -p "$out"
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
print("| config | spp | mean spp | time s | denoise s | Mrays | RMSE | relMSE | MAE | p99 | bias² | variance |")
print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
for c in cells:
    bv = (num(c["bias2"]), num(c["variance"])) if "bias2" in c else ("", "")
    print("| `%s` | %d | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s |" % (
        c["config"], c["spp"], num(c.get("meanSpp", c["spp"])), num(c["seconds"]),
        num(c["denoiseSeconds"]) if c.get("denoise") else "", num(c["rays"] * 1e-6), num(c["rmse"]),
        num(c["relMse"]), num(c["mae"]), num(c["p99"]), *bv))
print()
noise = traced["reference"].get("noiseRmse")
if noise is not None:
    print("Reference noise (RMSE of the gi reference itself): %s. Screen-space R = %s." % (num(noise), r))
    print()

print("| RMSE target | fastest cell reaching it |")
print("|---:|---|")
def fastest(pool, t):
    ok = [c for c in pool if c["rmse"] <= t]
    if not ok:
        return "not reached"
    b = min(ok, key=lambda c: c["seconds"])
    mean = " (mean %s)" % num(b["meanSpp"]) if "targetError" in b else ""
    return "`%s` @ %d spp%s, %s s" % (b["config"], b["spp"], mean, num(b["seconds"]))
for t in (x["rmse"] for x in traced["targets"]):
    print("| %s | %s |" % (num(t), fastest(cells, t)))
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
} >docs/trade.md
echo "== wrote docs/trade.md ($((SECONDS - start)) s in all)"
