#!/usr/bin/env python3
"""Figure 4 of VO from `obscura_bench_vo_sets --figure4` output: an SVG plot
and the Markdown tables of docs/vo_sample_sets.md.

    build/bench/obscura_bench_vo_sets --figure4 > fig4.csv
    python3 bench/vo_sets_plot.py fig4.csv docs/vo_sample_sets.svg > tables.md

The noise of a count is the mean, over the planes and creases, of the variance
over random rotations of the set. A count is a dip when its noise is below
the geometric mean of its neighbours' (n - 1, n + 1): the ratio column is
noise(n) / sqrt(noise(n - 1) noise(n + 1)), and a dip's ratio is < 1. The
counts VO §4.5 names as unusually good are marked with *.
"""
import csv
import math
import sys

PAPER = {  # VO §4.5
    "lines+centre": {5, 7, 9, 13, 16},
    "lines": {12, 13, 15},
    "points": {6, 12, 33},
}
TITLES = {
    "lines+centre": "lines, centre included",
    "lines": "lines, no centre",
    "points": "points",
}


def read(path):
    data = {}  # (samples, generator) -> {n: (noise, se, mse, diff from n - 1, its paired SE)}
    with open(path) as f:
        rows = [r for r in f if not r.startswith("#")]
    for r in csv.DictReader(rows):
        noise = 0.5 * (float(r["var_plane"]) + float(r["var_crease"]))
        se = 0.5 * math.hypot(float(r["se_plane"]), float(r["se_crease"]))
        mse = 0.5 * (float(r["mse_plane"]) + float(r["mse_crease"]))
        diff = float(r["diff_prev"]) if r["diff_prev"] else None
        sed = float(r["se_diff_prev"]) if r["se_diff_prev"] else None
        data.setdefault((r["samples"], r["generator"]), {})[int(r["n"])] = (noise, se, mse, diff, sed)
    return data


def ratio(series, n):
    if n - 1 in series and n + 1 in series:
        return series[n][0] / math.sqrt(series[n - 1][0] * series[n + 1][0])
    return None


def tables(data):
    out = []
    for samples in ("lines+centre", "lines", "points"):
        rel, opt = data[(samples, "relaxed")], data[(samples, "optimised")]
        out.append(f"**{TITLES[samples]}** (noise ×10⁴ ± SE; ratio to the neighbours' geometric mean; "
                   f"noise(n) − noise(n − 1) ×10⁴ in SEs of the paired difference; MSE against the exact V ×10⁴)\n")
        out.append("| n | relaxed | ratio | Δ/SE | MSE | optimised | ratio | Δ/SE | MSE |")
        out.append("|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
        for n in sorted(rel):
            cells = [f"{n}{' *' if n in PAPER[samples] else ''}"]
            for s in (rel, opt):
                noise, se, mse, diff, sed = s[n]
                r = ratio(s, n)
                rs = "" if r is None else (f"**{r:.3f}**" if r < 1 else f"{r:.3f}")
                ds = "" if diff is None else f"{diff / sed:+.1f}"
                cells += [f"{noise * 1e4:.3f} ± {se * 1e4:.3f}", rs, ds, f"{mse * 1e4:.3f}"]
            out.append("| " + " | ".join(cells) + " |")
        out.append("")
    return "\n".join(out)


def svg(data, path):
    panels = ("lines+centre", "lines", "points")
    W, H, L, T, PW, PH, GAP = 1020, 330, 60, 40, 280, 230, 50
    colours = {"relaxed": "#1f77b4", "optimised": "#d62728"}
    s = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" font-family="sans-serif" font-size="11">',
         f'<rect width="{W}" height="{H}" fill="white"/>']
    for p, samples in enumerate(panels):
        x0 = L + p * (PW + GAP)
        ns = sorted(data[(samples, "relaxed")])
        vals = [v[0] for g in colours for v in data[(samples, g)].values()]
        lo, hi = math.floor(math.log10(min(vals))), math.ceil(math.log10(max(vals)))
        X = lambda n: x0 + (n - ns[0]) / (ns[-1] - ns[0]) * PW
        Y = lambda v: T + PH - (math.log10(v) - lo) / (hi - lo) * PH
        s.append(f'<rect x="{x0}" y="{T}" width="{PW}" height="{PH}" fill="none" stroke="#888"/>')
        s.append(f'<text x="{x0 + PW / 2}" y="{T - 12}" text-anchor="middle" font-size="13">{TITLES[samples]}</text>')
        for e in range(lo, hi + 1):
            s.append(f'<line x1="{x0}" x2="{x0 + PW}" y1="{Y(10 ** e):.1f}" y2="{Y(10 ** e):.1f}" stroke="#ddd"/>')
            s.append(f'<text x="{x0 - 4}" y="{Y(10 ** e) + 4:.1f}" text-anchor="end">1e{e}</text>')
        for n in ns:
            if n % 2 == 0 or n in PAPER[samples]:
                bold = ' font-weight="bold"' if n in PAPER[samples] else ""
                s.append(f'<text x="{X(n):.1f}" y="{T + PH + 14}" text-anchor="middle"{bold}>{n}</text>')
            if n in PAPER[samples]:
                s.append(f'<line x1="{X(n):.1f}" x2="{X(n):.1f}" y1="{T}" y2="{T + PH}" stroke="#bbb" '
                         f'stroke-dasharray="3,3"/>')
        s.append(f'<text x="{x0 + PW / 2}" y="{T + PH + 30}" text-anchor="middle">samples n</text>')
        for g, c in colours.items():
            pts = data[(samples, g)]
            s.append('<polyline fill="none" stroke="%s" stroke-width="1.5" points="%s"/>' %
                     (c, " ".join(f"{X(n):.1f},{Y(pts[n][0]):.1f}" for n in sorted(pts))))
            for n in sorted(pts):
                s.append(f'<circle cx="{X(n):.1f}" cy="{Y(pts[n][0]):.1f}" r="2.2" fill="{c}"/>')
    s.append(f'<text x="{L}" y="{H - 8}">variance over random rotations (mean over planes and creases), log scale; '
             f'dashed: counts VO §4.5 names as unusually good</text>')
    for i, (g, c) in enumerate(colours.items()):
        s.append(f'<rect x="{W - 260 + i * 120}" y="{H - 18}" width="10" height="10" fill="{c}"/>'
                 f'<text x="{W - 246 + i * 120}" y="{H - 9}">{g}</text>')
    s.append("</svg>")
    with open(path, "w") as f:
        f.write("\n".join(s) + "\n")


if __name__ == "__main__":
    d = read(sys.argv[1])
    if len(sys.argv) > 2:
        svg(d, sys.argv[2])
    print(tables(d))
