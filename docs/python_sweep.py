#!/usr/bin/env python3
"""Notebook-style sweep with the Python module (docs/python.md "Python"): how far
should ambient rays reach? For ao, obscurance and transfer, render the scene
at several `distance` values and plot each one's error against a gi
reference versus its render time. The scene is loaded (and its BVH built)
once; every render reuses it, and no file is written but the plot.

    PYTHONPATH=build/python python3 docs/python_sweep.py -o sweep.png
    PYTHONPATH=build/python python3 docs/python_sweep.py --res 160x90 --spp 16 --reference-spp 256 -o sweep.png

The error is `obscura compare`'s RMSE (docs/compare.md "Compare"): W = RGB / A over
the pixels the reference covers fully and the pass covers at all.
"""
import argparse
import os

import matplotlib

matplotlib.use("Agg")  # no display needed
import matplotlib.pyplot as plt
import numpy as np

import obscura

here = os.path.dirname(os.path.abspath(__file__))
parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("--scene", default=os.path.join(here, "..", "scenes", "default.gltf"))
parser.add_argument("--res", default="320x180", help="WIDTHxHEIGHT")
parser.add_argument("--spp", type=int, default=16, help="samples per pixel of the swept renders")
parser.add_argument("--reference-spp", type=int, default=1024, help="samples per pixel of the gi reference")
parser.add_argument("--distances", default="0.25,0.5,1,2,4,inf", help="the `distance` values swept")
parser.add_argument("--falloff", default="sqrt",
                    help="obscurance's and transfer's falloff (step would make obscurance ao itself)")
parser.add_argument("-o", "--output", default="python_sweep.png", help="the plot (PNG)")
args = parser.parse_args()
width, height = (int(v) for v in args.res.split("x"))

scene = obscura.Scene(args.scene)
print(f"{args.scene}: {scene.triangles} triangles, loaded in {scene.load_seconds:.3f} s (BVH {scene.bvh_seconds:.3f} s)")


def pass_w(result):
    """Un-premultiplied W (H x W x 3) and coverage A."""
    a = result["A"]
    rgb = result.rgb
    with np.errstate(invalid="ignore", divide="ignore"):
        w = np.where(a[..., None] > 0, rgb / a[..., None], 0.0)
    return w, a


ref = obscura.render(scene, "gi", spp=args.reference_spp, res=(width, height), seed=1)
ref_w, ref_a = pass_w(ref)
print(f"gi reference: {args.reference_spp} spp in {ref.stats['seconds']:.2f} s")


def rmse(result):
    w, a = pass_w(result)
    mask = (ref_a == 1.0) & (a > 0)
    return float(np.sqrt(np.mean((w[mask] - ref_w[mask]) ** 2)))


fig, ax = plt.subplots(figsize=(7, 4.5))
for integrator, marker in (("ao", "o"), ("obscurance", "s"), ("transfer", "^")):
    times, errors = [], []
    for d in args.distances.split(","):
        params = {"distance": d} if integrator == "ao" else {"distance": d, "falloff": args.falloff}
        r = obscura.render(scene, integrator, params, spp=args.spp, res=(width, height))
        times.append(r.stats["seconds"])
        errors.append(rmse(r))
        print(f"{integrator:10s} distance={d:5s} {times[-1]:.3f} s  RMSE {errors[-1]:.4f}")
        ax.annotate(d, (times[-1], errors[-1]), textcoords="offset points", xytext=(4, 3), fontsize=7)
    ax.plot(times, errors, marker=marker, label=integrator if integrator == "ao" else f"{integrator} ({args.falloff})")
ax.set_xlabel(f"render time (s), {args.spp} spp at {width}x{height}")
ax.set_ylabel("RMSE against gi")
ax.set_title(f"distance sweep: {os.path.basename(args.scene)} (labels: distance)")
ax.grid(alpha=0.3)
ax.legend()
fig.tight_layout()
fig.savefig(args.output, dpi=120)
print(f"wrote {args.output}")
