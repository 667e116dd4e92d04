"""docs/temporal.md against bench/temporal.py, and the invariant that measurement
rests on: the frame number does not enter the sampler, so with a still camera
every frame of a --frames run is the same image, bit for bit, for every
screen-space pass (and any change between frames of a moving camera is the
move's). Run by CTest (python.tests) with PYTHONPATH=build/python and
OBSCURA_BINARY the CLI of the same build."""
import importlib.util
import os
import subprocess
import sys

import numpy as np

import obscura

SOURCE = os.environ.get("OBSCURA_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", ".."))
BINARY = os.environ.get("OBSCURA_BINARY", os.path.join(SOURCE, "build", "obscura"))


def bench():
    os.environ.pop("RADIUS", None)  # the doc's R
    spec = importlib.util.spec_from_file_location("temporal", os.path.join(SOURCE, "bench", "temporal.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def doc_tables():
    """The first column of each table between the script's markers in docs/temporal.md."""
    text = open(os.path.join(SOURCE, "docs", "temporal.md")).read()
    t = bench()
    body = text[text.index(t.BEGIN):text.index(t.END)]
    tables, rows = [], None
    for line in body.splitlines():
        if line.startswith("| pass"):
            rows = []
            tables.append(rows)
        elif line.startswith("|---"):
            continue
        elif line.startswith("| ") and rows is not None:
            rows.append([c.strip() for c in line.strip("|").split("|")])
        else:
            rows = None
    return tables


def test_the_docs_tables_list_the_scripts_passes():
    t = bench()
    specs = dict(t.passes())
    tables = doc_tables()
    assert len(tables) == 2 * len(t.settings()["steps"])
    band = []
    for base, _, _ in t.BAND:
        band += [("`%s`" % specs[base], "default"), ("`%s`" % specs[base], "0")]
    for main, guard in zip(tables[::2], tables[1::2]):
        assert [r[0] for r in main] == ["`%s`" % specs[layer] for layer, _, _ in t.ROWS]
        assert [(r[0], r[1]) for r in guard] == band


def test_a_still_camera_gives_identical_frames(tmp_path):
    move = str(tmp_path / "still.gltf")
    subprocess.run([sys.executable, os.path.join(SOURCE, "bench", "temporal_move.py"), move, "--frames", "2",
                    "--step", "0"], check=True)
    layers = []
    for layer, spec in bench().passes():
        if spec.split(":")[0] in ("vo", "ssat", "gtao"):
            layers += ["--pass", "%s=%s" % (layer, spec)]
    out = str(tmp_path / "f.####.exr")
    p = subprocess.run([BINARY, "render", move, "--frames", "0-2", "--res", "40x24", "--spp", "2", "-q", *layers,
                        "-o", out], capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr
    frames = [obscura.read_exr(out.replace("####", "%04d" % f)) for f in range(3)]
    assert len(layers) // 2 >= 20
    for later in frames[1:]:
        for name in frames[0].channel_names:
            assert np.array_equal(frames[0][name], later[name], equal_nan=True), name
