#!/usr/bin/env python3
"""Temporal stability of the screen-space passes, measured (docs/temporal.md).

    bench/temporal.py OUT                 # render (or reuse) and print the tables
    bench/temporal.py OUT --doc           # ... and rewrite docs/temporal.md's tables

For each STEP (a run each, in OUT/stepSTEP):
1. bench/temporal_move.py writes OUT/stepSTEP/move.gltf: scenes/default.gltf with its
   camera brought DOLLY units closer and trucking sideways, STEP scene units
   a frame over frames 0..FRAMES.
2. For each seed in SEEDS, one `obscura render OUT/move.gltf --frames 0-FRAMES`
   renders every pass of ROWS, TWINS and BAND as a layer (`--pass`) into OUT/stepSTEP/seedS/f.####.exr
   (RES, SPP camera samples = G-buffer layers, THREADS). The seed is the same for
   every frame of a --frames run (an image is a pure function of scene,
   settings and seed; the frame number does not enter the sampler), so each
   pixel keeps its random numbers from frame to frame, as a real-time renderer's
   fixed noise texture does.
3. Per frame pair (t, t+1) and pass X, with D_s = X_s(t+1) - X_s(t) of seed s,
   over the pixels the mask keeps (below), the script prints the medians over
   the pairs of:
     change   RMS of D_0: what a viewer of the seed-0 frames sees change;
     f        sampling flicker, sqrt(mean((D_0 - D_1)^2) / 2): the RMS of the
              change of X's Monte Carlo error, D_s - E[D] (the two seeds'
              errors are independent, so the true change cancels exactly and
              E[(D_0 - D_1)^2] = 2 Var D); p99: the 99th percentile of
              |D_0 - D_1| / sqrt(2);
   E[.] is the expectation over seeds at this SPP (for an unbiased pass, the
   converged value).
     beta     depth-buffer flicker: the RMS over pixels of E[D(X)] - E[D(X')],
              X' the traced twin (`depth=traced`, the same estimator and
              samples without the depth buffer), i.e. how the converged pass's
              change departs from its twin's. With G_s = D_s(X) - D_s(X'),
              beta^2 = mean(((G_0 + G_1)/2)^2) - mean((G_0 - G_1)^2)/4,
              unbiased (the noise the mean of two seeds keeps is subtracted);
     F        flicker, sqrt(f^2 + beta^2) = RMS of D(X) - E[D(X')]: the
              change beyond the twin's converged change; for a twin, and for
              `ao`/`obscurance`, F = f;
     true     the twin's converged change, RMS of E[D(X')] (noise removed as
              for beta): what the pass should change by under the move;
     fresh    sqrt(mean over the pair of (X_0 - X_1)^2): the noise change a new
              seed every frame would add, for comparison with f.
   The mask keeps pixels that are covered (A = 1) in both seeds and both frames
   and whose camera sample hit the same surface in both seeds (depths within
   2 %, normals within 25 degrees): at 1 spp a pixel on an edge jumps between
   surfaces as the edge crosses its sample (geometric aliasing, the same for
   every pass); the first line of each section gives the share kept. The guard-band
   table splits the kept pixels into the border (within BORDER px of the image's
   edge) and the rest, and adds the static bias against the twin there,
   b^2 = mean(((E_0 + E_1)/2)^2) - mean((E_0 - E_1)^2)/4, E_s = X_s - X'_s.

Environment: BUILD_DIR (build), RES (320x180), SPP (1), FRAMES (16),
STEPS (0.04,0.005: one run each), DOLLY (3.5), SEEDS (0,1), THREADS (2), BORDER (8), RADIUS (0.5).
Renders are kept in OUT/stepSTEP and reused when the settings match
(settings.txt there).
"""

import os
import subprocess
import sys
import time

import numpy as np

ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
DOC = os.path.join(ROOT, "docs", "temporal.md")
RADIUS = os.environ.get("RADIUS", "0.5")


def spec(s):
    return s.format(R=RADIUS)


# (layer, integrator spec, traced twin's layer). A twin is a layer of its own,
# listed in TWINS; vo's area samples have none (depth=traced reads no moments),
# so they are held to the line samples' twin with the same interleave. VO's
# section 5 pair: 12 points against 5 lines. `ao` and `obscurance`, the
# ray-traced passes, take 16 rays per camera sample: the screen-space passes'
# 16 samples per pixel and layer.
ROWS = [
    ("vo_point", "vo:samples=point,interleave=off,radius={R}", "vo_point_t"),
    ("vo_point_il", "vo:samples=point,interleave=on,radius={R}", "vo_point_il_t"),
    ("vo_line", "vo:samples=line,interleave=off,radius={R}", "vo_line_t"),
    ("vo_line_il", "vo:samples=line,interleave=on,radius={R}", "vo_line_il_t"),
    ("vo_area", "vo:samples=area,interleave=off,radius={R}", "vo_line_t"),
    ("vo_area_il", "vo:samples=area,interleave=on,radius={R}", "vo_line_il_t"),
    ("vo_point12", "vo:samples=point,count=12,interleave=off,radius={R}", None),
    ("vo_line5", "vo:samples=line,count=5,interleave=off,radius={R}", None),
    ("ssat", "ssat:interleave=on,distance={R}", "ssat_t"),
    ("ssat_off", "ssat:interleave=off,distance={R}", "ssat_off_t"),
    ("gtao", "gtao:interleave=on,radius={R}", "gtao_t"),
    ("gtao_off", "gtao:interleave=off,radius={R}", "gtao_off_t"),
    ("ao", "ao:distance={R},rays=16", None),
    ("obscurance", "obscurance:falloff=sqrt,distance={R},rays=16", None),
]
TWINS = [
    ("vo_point_t", "vo:samples=point,interleave=off,radius={R},depth=traced"),
    ("vo_point_il_t", "vo:samples=point,interleave=on,radius={R},depth=traced"),
    ("vo_line_t", "vo:samples=line,interleave=off,radius={R},depth=traced"),
    ("vo_line_il_t", "vo:samples=line,interleave=on,radius={R},depth=traced"),
    ("ssat_t", "ssat:interleave=on,distance={R},depth=traced"),
    ("ssat_off_t", "ssat:interleave=off,distance={R},depth=traced"),
    ("gtao_t", "gtao:interleave=on,radius={R},depth=traced"),
    ("gtao_off_t", "gtao:interleave=off,radius={R},depth=traced"),
]
# The guard band: the default (-1) against none, at the border and inside.
BAND = [
    ("vo_line", "vo_line_nb", "vo:samples=line,interleave=off,radius={R},guard-band=0"),
    ("ssat", "ssat_nb", "ssat:interleave=on,distance={R},guard-band=0"),
    ("gtao", "gtao_nb", "gtao:interleave=on,radius={R},guard-band=0"),
]


def passes():
    out = [(layer, s) for layer, s, _ in ROWS] + TWINS + [(nb, s) for _, nb, s in BAND]
    return [(layer, spec(s)) for layer, s in out]


def twin_of(layer):
    return {r[0]: r[2] for r in ROWS}.get(layer)


def settings():
    return {
        "build": os.path.join(ROOT, os.environ.get("BUILD_DIR", "build")),
        "res": os.environ.get("RES", "320x180"),
        "spp": os.environ.get("SPP", "1"),
        "frames": int(os.environ.get("FRAMES", "16")),
        "steps": os.environ.get("STEPS", "0.04,0.005").split(","),
        "dolly": os.environ.get("DOLLY", "3.5"),
        "seeds": [int(s) for s in os.environ.get("SEEDS", "0,1").split(",")],
        "threads": os.environ.get("THREADS", "2"),
        "border": int(os.environ.get("BORDER", "8")),
    }


def render(out, st):
    binary = os.path.join(st["build"], "obscura")
    if not os.access(binary, os.X_OK):
        sys.exit("temporal.py: %s is not built (ninja obscura obscura_python)" % binary)
    key = "res %s spp %s frames %d step %s dolly %s radius %s\n%s\n" % (
        st["res"], st["spp"], st["frames"], st["step"], st["dolly"], RADIUS, " ".join("%s=%s" % p for p in passes()))
    os.makedirs(out, exist_ok=True)
    keyfile = os.path.join(out, "settings.txt")
    if not os.path.exists(keyfile) or open(keyfile).read() != key:
        for name in os.listdir(out):
            if name.startswith("seed"):
                for f in os.listdir(os.path.join(out, name)):
                    os.remove(os.path.join(out, name, f))
        with open(keyfile, "w") as f:
            f.write(key)
    move = os.path.join(out, "move.gltf")
    subprocess.run([sys.executable, os.path.join(ROOT, "bench", "temporal_move.py"), move,
                    "--frames", str(st["frames"]), "--step", st["step"], "--dolly", st["dolly"]], check=True)
    layers = []
    for layer, s in passes():
        layers += ["--pass", "%s=%s" % (layer, s)]
    for seed in st["seeds"]:
        d = os.path.join(out, "seed%d" % seed)
        os.makedirs(d, exist_ok=True)
        if os.path.exists(os.path.join(d, "f.%04d.exr" % st["frames"])):
            continue
        t0 = time.time()
        subprocess.run([binary, "render", move, "--frames", "0-%d" % st["frames"], "--res", st["res"],
                        "--spp", st["spp"], "--seed", str(seed), "--threads", st["threads"], "-q",
                        "--primary", "ao", *layers, "-o", os.path.join(d, "f.####.exr")], check=True)
        print("rendered seed %d: %d frames, %.0f s" % (seed, st["frames"] + 1, time.time() - t0), file=sys.stderr)


def load(out, st, frame):
    import obscura  # the module of this build: PYTHONPATH=BUILD_DIR/python
    images = []
    for seed in st["seeds"][:2]:
        im = obscura.read_exr(os.path.join(out, "seed%d" % seed, "f.%04d.exr" % frame))
        layers = {layer: np.asarray(im[layer + ".R"], dtype=np.float64) for layer, _ in passes()}
        n = np.stack([np.asarray(im["N." + c], dtype=np.float64) for c in "XYZ"])
        images.append((layers, np.asarray(im["A"]), np.asarray(im["Z"], dtype=np.float64), n))
    return images


def surface_mask(a, b):
    """Pixels covered in both seeds whose samples hit the same surface."""
    (_, a0, z0, n0), (_, a1, z1, n1) = a, b
    return ((a0 == 1) & (a1 == 1) & (np.abs(z0 - z1) <= 0.02 * np.maximum(z0, z1)) &
            (np.sum(n0 * n1, axis=0) >= np.cos(np.radians(25))))


def pair_stats(prev, cur, mask, border):
    """Per-layer statistics of one frame pair over the mask (and its border split)."""
    h, w = mask.shape
    yy, xx = np.mgrid[0:h, 0:w]
    strip = (xx < border) | (xx >= w - border) | (yy < border) | (yy >= h - border)
    regions = {"all": mask, "border": mask & strip, "inner": mask & ~strip}
    d = {layer: [cur[s][0][layer] - prev[s][0][layer] for s in (0, 1)] for layer, _ in passes()}
    e = {layer: [cur[s][0][layer] - cur[1 - s][0][layer] for s in (0, 1)] for layer, _ in passes()}
    e_prev = {layer: prev[0][0][layer] - prev[1][0][layer] for layer, _ in passes()}
    stats = {}
    for region, m in regions.items():
        if not m.any():
            continue
        mean = lambda x: float(np.mean(x[m]))
        for layer, _ in passes():
            d0, d1 = d[layer]
            s = {"change2": mean(d0 ** 2), "f2": mean((d0 - d1) ** 2) / 2,
                 "p99": float(np.percentile(np.abs(d0 - d1)[m], 99)) / np.sqrt(2),
                 "fresh2": (mean(e_prev[layer] ** 2) + mean(e[layer][0] ** 2)) / 2,
                 "true2": mean(((d0 + d1) / 2) ** 2) - mean((d0 - d1) ** 2) / 4}
            stats[(region, layer)] = s
        for layer, _, twin in ROWS:
            pairs = [(layer, twin)] if twin else []
            pairs += [(nb, twin) for base, nb, _ in BAND if base == layer and twin]
            for x, t in pairs:
                g0, g1 = d[x][0] - d[t][0], d[x][1] - d[t][1]
                s = stats[(region, x)]
                s["beta2"] = mean(((g0 + g1) / 2) ** 2) - mean((g0 - g1) ** 2) / 4
                s["twin_true2"] = stats[(region, t)]["true2"]
                b0 = cur[0][0][x] - cur[0][0][t]
                b1 = cur[1][0][x] - cur[1][0][t]
                s["bias2"] = mean(((b0 + b1) / 2) ** 2) - mean((b0 - b1) ** 2) / 4
    return stats


def analyse(out, st):
    per_pair, kept, covered = [], [], []
    prev = load(out, st, 0)
    for t in range(1, st["frames"] + 1):
        cur = load(out, st, t)
        mask = surface_mask(prev[0], prev[1]) & surface_mask(cur[0], cur[1])
        cov = (prev[0][1] == 1) & (prev[1][1] == 1) & (cur[0][1] == 1) & (cur[1][1] == 1)
        kept.append(mask.sum())
        covered.append(cov.sum())
        per_pair.append(pair_stats(prev, cur, mask, st["border"]))
        prev = cur
    return per_pair, kept, covered


def median(per_pair, region, layer, key, root=True):
    v = float(np.median([p[(region, layer)][key] for p in per_pair if (region, layer) in p]))
    return np.sqrt(max(v, 0.0)) if root else v


def fmt(x):
    return "%.4f" % x


def tables(per_pair, kept, covered, st):
    lines = []
    h, w = (int(x) for x in reversed(st["res"].split("x")))
    lines.append("Frames 0-%d of bench/temporal_move.py's truck (STEP %s scene units a frame, DOLLY %s), %s, SPP %s, "
                 "seeds %s; R = %s. Medians over the %d frame pairs. Kept pixels: %.1f %% of the frame "
                 "(%.1f %% of the covered ones; the rest straddle an edge)." % (
                     st["frames"], st["step"], st["dolly"], st["res"], st["spp"], ",".join(map(str, st["seeds"][:2])), RADIUS,
                     len(per_pair), 100 * np.median(kept) / (h * w), 100 * np.median(kept) / np.median(covered)))
    lines.append("")
    lines.append("| pass | twin | change | true | F | twin F | F / twin F | f | f p99 | twin f p99 | beta | fresh |")
    lines.append("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    specs = dict(passes())
    for layer, _, twin in ROWS:
        f2 = median(per_pair, "all", layer, "f2", False)
        own = twin and specs[twin] == specs[layer] + ",depth=traced"
        row = ["`%s`" % specs[layer], ("`depth=traced`" if own else "`%s`" % specs[twin]) if twin else "",
               fmt(median(per_pair, "all", layer, "change2"))]
        if twin:
            beta2 = median(per_pair, "all", layer, "beta2", False)
            flick = np.sqrt(float(np.median([p[("all", layer)]["f2"] + p[("all", layer)]["beta2"] for p in per_pair])))
            tf = median(per_pair, "all", twin, "f2")
            row += [fmt(median(per_pair, "all", twin, "true2")), fmt(flick), fmt(tf), "%.2f" % (flick / tf),
                    fmt(np.sqrt(f2)), fmt(median(per_pair, "all", layer, "p99", False)),
                    fmt(median(per_pair, "all", twin, "p99", False)), fmt(np.sqrt(max(beta2, 0)))]
        else:
            row += [fmt(median(per_pair, "all", layer, "true2")), fmt(np.sqrt(f2)), "", "", fmt(np.sqrt(f2)),
                    fmt(median(per_pair, "all", layer, "p99", False)), "", ""]
        row.append(fmt(median(per_pair, "all", layer, "fresh2")))
        lines.append("| " + " | ".join(row) + " |")
    lines.append("")
    lines.append("Guard band: the default (`guard-band=-1`) against none (`guard-band=0`), within %d px of the "
                 "image's edge (border) and elsewhere (inner); b is the static error against the twin." % st["border"])
    lines.append("")
    lines.append("| pass | guard band | border b | border beta | border f | inner b | inner beta | inner f |")
    lines.append("|---|---|---:|---:|---:|---:|---:|---:|")
    for base, nb, _ in BAND:
        for layer, band in ((base, "default"), (nb, "0")):
            row = ["`%s`" % specs[base].split(",guard-band")[0], band]
            for region in ("border", "inner"):
                row += [fmt(median(per_pair, region, layer, "bias2")), fmt(median(per_pair, region, layer, "beta2")),
                        fmt(median(per_pair, region, layer, "f2"))]
            lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines)


BEGIN, END = "<!-- bench/temporal.py: begin -->", "<!-- bench/temporal.py: end -->"


def main():
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    if len(args) != 1 or any(a not in ("--doc",) for a in sys.argv[1:] if a.startswith("--")):
        sys.exit(__doc__.split("\n\n")[1])
    base, st = args[0], settings()
    if len(st["seeds"]) != 2:
        sys.exit("temporal.py: SEEDS must name two seeds")
    sys.path.insert(0, os.path.join(st["build"], "python"))
    sections = []
    for step in st["steps"]:
        st["step"] = step
        out = os.path.join(base, "step" + step)
        render(out, st)
        sections.append("### STEP %s\n\n" % step + tables(*analyse(out, st), st))
        print(sections[-1] + "\n", flush=True)
    text = "\n\n".join(sections)
    if "--doc" in sys.argv:
        doc = open(DOC).read()
        i, j = doc.index(BEGIN) + len(BEGIN), doc.index(END)
        with open(DOC + ".tmp", "w") as f:
            f.write(doc[:i] + "\n" + text + "\n" + doc[j:])
        os.replace(DOC + ".tmp", DOC)


if __name__ == "__main__":
    main()
