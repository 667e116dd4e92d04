"""The Python module against the CLI (docs/python.md "Python"): a render from Python
equals `obscura render` with the same settings channel for channel, bit for
bit; errors raise obscura.Error with the CLI's message; a scene loaded once
renders many times; Ctrl-C stops a render; the GIL is released while one runs.

Run by CTest (python.tests) with PYTHONPATH=build/python and OBSCURA_BINARY
the CLI of the same build."""
import base64
import json
import os
import signal
import struct
import subprocess
import threading
import time
import warnings

import numpy as np
import pytest

import obscura

SOURCE = os.environ.get("OBSCURA_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", ".."))
BINARY = os.environ.get("OBSCURA_BINARY", os.path.join(SOURCE, "build", "obscura"))
SCENE = os.path.join(SOURCE, "scenes", "default.gltf")
# Attributes that differ between two runs of the same render: its times, the
# write's date, and the threads TBB had (the same setting, another count).
VARYING = {"obscura:renderTime", "obscura:bvhBuildTime", "capDate", "obscura:denoiseTime"}


@pytest.fixture(scope="module")
def scene():
    return obscura.Scene(SCENE)


def cli(*args):
    """Runs the CLI; returns (exit code, stderr)."""
    p = subprocess.run([BINARY, *args], capture_output=True, text=True, timeout=300)
    return p.returncode, p.stderr


def same_bits(a, b):
    # Bit patterns, so NaN == NaN and -0 != +0: "equal" means the same file.
    return a.shape == b.shape and np.array_equal(a.view(np.uint32), b.view(np.uint32))


def assert_same_image(a, b):
    assert a.channel_names == b.channel_names or sorted(a.channel_names) == sorted(b.channel_names)
    for name in a.channel_names:
        assert same_bits(np.asarray(a[name]), np.asarray(b[name])), name


# Each case: the keyword arguments of render() and the same render's CLI flags.
CASES = [
    (dict(integrator="ao", params={"distance": 2}, spp=4, res=(64, 36), seed=3),
     ["-i", "ao", "-p", "distance=2", "--spp", "4", "--res", "64x36", "--seed", "3"]),
    (dict(passes={"obs": "obscurance:distance=1,falloff=sqrt", "tr": "transfer:depth=1"}, spp=3, res=(48, 27),
          camera="top", sky=(1.0, 0.5, 0.25), filter="gaussian", cryptomatte="object"),
     ["--pass", "obs=obscurance:distance=1,falloff=sqrt", "--pass", "tr=transfer:depth=1", "--spp", "3",
      "--res", "48x27", "--camera", "top", "--sky", "1.0,0.5,0.25", "--filter", "gaussian", "--cryptomatte", "object"]),
    (dict(integrator="gi", spp=2, res=(40, 30), region=(8, 4, 30, 20), aovs=False, seed=7),
     ["-i", "gi", "--spp", "2", "--res", "40x30", "--region", "8,4,30,20", "--no-aovs", "--seed", "7"]),
    (dict(integrator="ao", spp=16, res=(48, 27), target_error=0.05, min_spp=4, denoise=True),
     ["-i", "ao", "--spp", "16", "--res", "48x27", "--target-error", "0.05", "--min-spp", "4", "--denoise"]),
    (dict(integrator="ao", spp=32, res=(48, 27), target_error=0.05, min_spp=8, background_spp=2, camera="top"),
     ["-i", "ao", "--spp", "32", "--res", "48x27", "--target-error", "0.05", "--min-spp", "8",
      "--background-spp", "2", "--camera", "top"]),
    (dict(integrator="ao", spp=16, res=(48, 27), target_error=0.05, denoise=True, albedo=False),
     ["-i", "ao", "--spp", "16", "--res", "48x27", "--target-error", "0.05", "--denoise", "--no-albedo"]),
]


@pytest.mark.parametrize("kwargs,flags", CASES, ids=["ao", "passes", "gi-region", "adaptive-denoise", "survey", "no-albedo"])
def test_render_equals_cli(scene, tmp_path, kwargs, flags):
    kwargs = dict(kwargs)
    integrator = kwargs.pop("integrator", None)
    params = kwargs.pop("params", None)
    result = obscura.render(scene, integrator, params, **kwargs)
    cli_exr = str(tmp_path / "cli.exr")
    code, err = cli("render", SCENE, "-o", cli_exr, "-q", *flags)
    assert code == 0, err
    from_cli = obscura.read_exr(cli_exr)
    # The in-memory channels, and the file result.write() writes.
    assert_same_image(result, from_cli)
    if kwargs.get("albedo") is False:
        assert "albedo.R" not in result.channel_names and "N.X" in result.channel_names
    py_exr = str(tmp_path / "py.exr")
    result.write(py_exr)
    written = obscura.read_exr(py_exr)
    assert_same_image(written, from_cli)
    a, b = written.header, from_cli.header
    assert set(a) == set(b)
    for k in set(a) - VARYING:
        if isinstance(a[k], np.ndarray):
            assert np.array_equal(a[k], b[k]), k
        else:
            assert a[k] == b[k], k
    # The header as a dict: the attributes render() recorded, as written.
    for k, v in result.header.items():
        if k not in VARYING:
            assert np.array_equal(v, a[k]) if isinstance(v, np.ndarray) else v == a[k], k


def test_scene_options_match_cli(scene, tmp_path):
    """A Scene built again from the parsed file with other options (a frame,
    object roles, robust traversal) renders as the CLI does with them."""
    posed = scene.with_options(frame=12, fps=25, objects=["crate*:occluder=false"], robust=True)
    assert posed.path == scene.path and posed.triangles == scene.triangles
    result = obscura.render(posed, "ao", spp=2, res=(48, 27))
    cli_exr = str(tmp_path / "cli.exr")
    code, err = cli("render", SCENE, "-o", cli_exr, "-q", "--spp", "2", "--res", "48x27", "--frame", "12", "--fps", "25",
                    "--object", "crate*:occluder=false", "--robust")
    assert code == 0, err
    from_cli = obscura.read_exr(cli_exr)
    assert_same_image(result, from_cli)
    for k in ("obscura:frame", "obscura:fps", "obscura:objectOverrides", "obscura:objectRoles", "obscura:robust"):
        assert result.header[k] == from_cli.header[k], k
    assert posed.materials == scene.materials and "crate_body" in scene.materials


def test_regions_merge_to_the_full_render(scene, tmp_path):
    """obscura.merge of region renders written from Python equals the full render."""
    full = obscura.render(scene, "ao", spp=2, res=(40, 24), seed=5)
    tiles = []
    for i, region in enumerate([(0, 0, 40, 10), (0, 10, 40, 24)]):
        path = str(tmp_path / f"tile{i}.exr")
        obscura.render(scene, "ao", spp=2, res=(40, 24), seed=5, region=region).write(path)
        tiles.append(path)
    obscura.merge(str(tmp_path / "merged.exr"), tiles)
    assert_same_image(obscura.read_exr(str(tmp_path / "merged.exr")), full)


def test_channels_are_views(scene):
    r = obscura.render(scene, spp=1, res=(32, 18))
    a = r["R"]
    assert a.dtype == np.float32 and a.shape == (18, 32)
    assert not a.flags.writeable and not a.flags.owndata  # a view of the film, not a copy
    assert r.rgb.shape == (18, 32, 3) and same_bits(r.rgb[:, :, 1].copy(), r["G"].copy())
    assert r.layer("N").shape == (18, 32, 3)
    del r  # the array keeps the film alive
    assert np.isfinite(a).all()


def cli_error(*args):
    code, err = cli(*args)
    assert code != 0
    line = err.strip().splitlines()[-1]
    assert line.startswith("obscura: error: ")
    return line[len("obscura: error: "):]


@pytest.mark.parametrize("kwargs,flags", [
    (dict(spp=0), ["--spp", "0"]),
    (dict(integrator="nope"), ["-i", "nope"]),
    (dict(params={"distance": -1}), ["-p", "distance=-1"]),
    (dict(res=(0, 10)), ["--res", "0x10"]),
    (dict(camera="nowhere"), ["--camera", "nowhere"]),
    (dict(region=(0, 0, 100, 10), res=(64, 36)), ["--region", "0,0,100,10", "--res", "64x36"]),
    (dict(passes=["ao=ao", "ao=obscurance"]), ["--pass", "ao=ao", "--pass", "ao=obscurance"]),
    (dict(filter="tent"), ["--filter", "tent"]),
    (dict(threads=65537), ["--threads", "65537"]),
], ids=["spp", "integrator", "param", "res", "camera", "region", "passes", "filter", "threads"])
def test_errors_match_cli(scene, tmp_path, kwargs, flags):
    kwargs = dict(kwargs)
    integrator = kwargs.pop("integrator", None)
    params = kwargs.pop("params", None)
    with pytest.raises(obscura.Error) as e:
        obscura.render(scene, integrator, params, **kwargs)
    assert str(e.value) == cli_error("render", SCENE, "-o", str(tmp_path / "x.exr"), "-q", *flags)


def test_scene_errors_match_cli(tmp_path):
    missing = str(tmp_path / "missing.gltf")
    with pytest.raises(obscura.Error) as e:
        obscura.Scene(missing)
    assert str(e.value) == cli_error("render", missing, "-o", str(tmp_path / "x.exr"), "-q")
    with pytest.raises(obscura.Error) as e:
        obscura.Scene(SCENE, subdiv="bogus")
    assert str(e.value) == cli_error("render", SCENE, "-o", str(tmp_path / "x.exr"), "-q", "--subdiv", "bogus")
    with pytest.raises(obscura.Error) as e:
        obscura.Scene(SCENE, normal_maps="maybe")
    assert str(e.value) == cli_error("render", SCENE, "-o", str(tmp_path / "x.exr"), "-q", "--normal-maps", "maybe")


def test_degenerate_scene_with_automatic_camera_is_an_error(tmp_path):
    # A triangle whose three vertices are equal: the automatic camera has no
    # distance to stand back (Embree aborted the process on its NaN rays).
    path = tmp_path / "point.obj"
    path.write_text("v 1 2 3\nv 1 2 3\nv 1 2 3\nf 1 2 3\n")
    with pytest.raises(obscura.Error) as e:
        obscura.render(obscura.Scene(str(path)), "ao", spp=1, res=(8, 8))
    assert "the scene is 0 across" in str(e.value)
    assert str(e.value) == cli_error("render", str(path), "-o", str(tmp_path / "x.exr"), "-q",
                                     "--spp", "1", "--res", "8x8")


def test_deeply_nested_json_is_refused(tmp_path):
    # 30,000 arrays nested in extras overflowed the stack inside tinygltf and
    # killed Python; refused past 512 levels (docs/scenes.md).
    path = tmp_path / "deep.gltf"
    write_emissive_triangle(path)
    doc = path.read_text()
    n = 30000
    path.write_text(doc[:-1] + ', "extras": ' + "[" * n + "1" + "]" * n + "}")
    with pytest.raises(obscura.Error, match=r"the JSON nests 30001 arrays and objects deep .*at most 512 levels"):
        obscura.Scene(str(path))


def write_emissive_triangle(path):
    """A one-triangle glTF whose material is emissive: loading it warns
    (ambient passes ignore emission)."""
    positions = struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0)
    doc = {
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": len(positions),
                     "uri": "data:application/octet-stream;base64," + base64.b64encode(positions).decode()}],
        "bufferViews": [{"buffer": 0, "byteLength": len(positions)}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 0]}],
        "materials": [{"emissiveFactor": [1, 1, 1]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "material": 0}]}],
        "nodes": [{"mesh": 0}],
        "scenes": [{"nodes": [0]}],
        "scene": 0,
    }
    path.write_text(json.dumps(doc))
    return str(path)


def test_warnings_are_python_warnings(tmp_path, capfd):
    """The CLI's `obscura: warning: ...` lines reach Python as
    obscura.ObscuraWarning (a UserWarning), so filters and pytest.warns apply;
    nothing is printed."""
    first = write_emissive_triangle(tmp_path / "emissive.gltf")
    code, err = cli("render", first, "-o", str(tmp_path / "x.exr"), "--res", "8x8", "--spp", "1", "-q")
    assert code == 0 and f"obscura: warning: {first}: emission is ignored by ambient passes" in err
    with pytest.warns(obscura.ObscuraWarning, match="emission is ignored by ambient passes") as record:
        obscura.Scene(first)
    assert issubclass(obscura.ObscuraWarning, UserWarning)
    assert [str(w.message) for w in record] == [f"{first}: emission is ignored by ambient passes"]
    assert "warning" not in capfd.readouterr().err
    # A filter that makes it an error raises it (another file: each warning is given once).
    second = write_emissive_triangle(tmp_path / "emissive2.gltf")
    with warnings.catch_warnings():
        warnings.simplefilter("error", obscura.ObscuraWarning)
        with pytest.raises(obscura.ObscuraWarning, match="emission is ignored"):
            obscura.Scene(second)


def test_bad_keywords(scene):
    with pytest.raises(obscura.Error, match=r"render: unknown keyword argument 'sppp' \(known: integrator, params"):
        obscura.render(scene, sppp=4)
    with pytest.raises(obscura.Error, match=r"render: spp: expected an int, got str"):
        obscura.render(scene, spp="4")
    with pytest.raises(obscura.Error, match=r"render: denoise: expected True or False, got int"):
        obscura.render(scene, denoise=1)
    with pytest.raises(obscura.Error, match=r"Scene: unknown keyword argument 'subdivision'"):
        obscura.Scene(SCENE, subdivision="loop")
    r = obscura.render(scene, spp=1, res=(16, 9))
    with pytest.raises(obscura.Error, match=r"must end in .exr"):
        r.write("/tmp/out.tif")


def test_integrators_registry():
    listed = {i["name"]: i for i in obscura.integrators()}
    assert {"ao", "obscurance", "transfer", "gi"} <= set(listed)
    ao = {p["name"]: p for p in listed["ao"]["params"]}
    assert "distance" in ao and ao["distance"]["doc"] and listed["ao"]["kind"] == "ray-traced"
    # The same listing `obscura integrators` prints.
    out = subprocess.run([BINARY, "integrators"], capture_output=True, text=True, check=True).stdout
    for name, i in listed.items():
        assert i["doc"] in out
        for p in i["params"]:
            assert p["doc"] in out


def test_load_once_render_many(scene):
    """A sweep pays the scene load and BVH once; each render equals a render
    of a freshly loaded scene."""
    t0 = time.perf_counter()
    fresh = obscura.Scene(SCENE)
    load = time.perf_counter() - t0
    renders = []
    for d in (0.5, 1.0, 2.0):
        t0 = time.perf_counter()
        r = obscura.render(scene, "ao", {"distance": d}, spp=2, res=(64, 36))
        renders.append(time.perf_counter() - t0)
        assert_same_image(r, obscura.render(fresh, "ao", {"distance": d}, spp=2, res=(64, 36)))
    print(f"load+BVH {load:.4f} s (BVH {fresh.bvh_seconds:.4f} s), renders {', '.join(f'{t:.4f}' for t in renders)} s")


def test_ctrl_c_interrupts_render(scene):
    """SIGINT during a render (a minute's worth of samples) raises
    KeyboardInterrupt once the render loop sees the cancel flag."""
    timer = threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT))
    t0 = time.perf_counter()
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        obscura.render(scene, "gi", spp=1 << 20, res=(64, 36), threads=1)
    timer.join()
    assert time.perf_counter() - t0 < 20


def test_gil_released(scene):
    """Another Python thread runs while a render does."""
    ticks = 0
    stop = threading.Event()

    def count():
        nonlocal ticks
        while not stop.is_set():
            ticks += 1
            time.sleep(0.001)

    t = threading.Thread(target=count)
    t.start()
    r = obscura.render(scene, "gi", spp=1024, res=(64, 36), threads=1)  # about half a second
    stop.set()
    t.join()
    # A held GIL would stop the counter for the whole render; released, it
    # ticks every ms or so. At least one tick per 50 ms leaves room for a
    # loaded machine.
    assert ticks >= int(r.stats["seconds"] * 20), (ticks, r.stats["seconds"])


def test_compare_returns_the_table(tmp_path):
    rows = obscura.compare(SCENE, str(tmp_path / "cmp"), ["ao:distance=1", "obscurance:distance=1"], spp=[2],
                           reference_spp=8, res=(32, 18), targets_flip="0.5")
    assert [r["config"] for r in rows] == ["ao:distance=1", "obscurance:distance=1"]
    assert all(r["spp"] == 2 and r["rmse"] > 0 and r["time_s"] > 0 for r in rows)
    # One seed: one value per seed, and no interval (docs/compare.md "Uncertainty").
    assert all(len(r["seed_mse"]) == 1 and r["rmse_lo"] is None for r in rows)
    assert all(abs(r["seed_mse"][0] - r["rmse"] ** 2) <= 1e-6 * r["rmse"] ** 2 for r in rows)
    # FLIP (docs/compare.md "FLIP"): in (0, 1) for a noisy pass, at the default observer.
    assert all(0 < r["flip"] < 1 and 0 < r["flip_hdr"] < 1 and abs(r["flip_ppd"] - 67.0206) < 1e-3 for r in rows)
    # The CLI resumes the same directory: every cell is already there.
    code, err = cli("compare", SCENE, "-o", str(tmp_path / "cmp"), "-c", "ao:distance=1", "-c", "obscurance:distance=1",
                    "--spp", "2", "--reference-spp", "8", "--res", "32x18")
    assert code == 0 and "done earlier (kept)" in err, err


@pytest.mark.parametrize("call", ["render", "Scene", "compare"])
def test_docs_document_every_keyword(scene, call):
    """docs/python.md "Python" names every keyword each function takes (the list the
    unknown-keyword error gives), so the reference stays complete."""
    with open(os.path.join(SOURCE, "docs", "python.md")) as f:
        section = f.read()
    fn = {"render": lambda: obscura.render(scene, no_such_keyword=1),
          "Scene": lambda: obscura.Scene(SCENE, no_such_keyword=1),
          "compare": lambda: obscura.compare(SCENE, "/nonexistent", ["ao"], no_such_keyword=1)}[call]
    with pytest.raises(obscura.Error) as e:
        fn()
    known = str(e.value).split("(known: ")[1].rstrip(")").split(", ")
    assert len(known) > 3
    for name in known:
        assert f"`{name}`" in section, f"docs/python.md \"Python\" does not name {call}'s keyword `{name}`"


def test_checkpoint_resumes_in_the_cli(scene, tmp_path, monkeypatch):
    """A render from Python interrupted with checkpoint= leaves the CLI's
    checkpoint file: `obscura render --checkpoint` resumes it, and the image
    equals an uninterrupted render (docs/production.md "Checkpoints")."""
    out = str(tmp_path / "shot.exr")
    settings = dict(spp=256, res=(64, 48), seed=2, threads=1)  # 12 tiles, each tens of ms
    flags = ["-i", "gi", "--spp", "256", "--res", "64x48", "--seed", "2", "--threads", "1"]
    # The core's test hook: SIGINT right after the checkpoint holds 3 tiles.
    monkeypatch.setenv("OBSCURA_TEST_CHECKPOINT_KILL", "3:INT")
    with pytest.raises(KeyboardInterrupt):
        obscura.render(scene, "gi", checkpoint=0, checkpoint_file=out + ".checkpoint", **settings)
    monkeypatch.delenv("OBSCURA_TEST_CHECKPOINT_KILL")
    assert os.path.exists(out + ".checkpoint")
    code, err = cli("render", SCENE, "-o", out, "--checkpoint", "0", *flags)
    assert code == 0 and "resuming from" in err, err
    assert not os.path.exists(out + ".checkpoint")
    resumed = obscura.read_exr(out)
    assert resumed.header["obscura:checkpointRuns"] == 2
    assert_same_image(resumed, obscura.render(scene, "gi", **settings))
    with pytest.raises(obscura.Error, match="checkpoint and checkpoint_file go together"):
        obscura.render(scene, checkpoint=5)


def shared_scene(rel):
    """A third-party scene (README "Test scenes"): skipped when absent,
    unless OBSCURA_REQUIRE_SCENES is set (CI), as the C++ tests do."""
    root = os.environ.get("OBSCURA_SCENES") or os.environ.get("OBSCURA_DEFAULT_SCENES",
                                                               os.path.join(SOURCE, "..", "shared", "scenes"))
    path = os.path.join(root, rel)
    if not os.path.exists(path):
        if os.environ.get("OBSCURA_REQUIRE_SCENES", "0") not in ("", "0"):
            pytest.fail(f"{path}: scene absent (OBSCURA_REQUIRE_SCENES is set)")
        pytest.skip(f"{path}: scene absent")
    return path


def test_adaptive_subdivision_equals_cli(tmp_path):
    """subdiv_edge refines for the view given at load; renders of that view
    equal the CLI's, another view is refused."""
    cage = shared_scene("spot_cage/spot_control_mesh.obj")
    scene = obscura.Scene(cage, subdiv="catmull-clark", subdiv_edge=4, res=(64, 48))
    result = obscura.render(scene, spp=2)
    out = str(tmp_path / "cli.exr")
    code, err = cli("render", cage, "-o", out, "-q", "--subdiv", "catmull-clark", "--subdiv-edge", "4", "--res", "64x48",
                    "--spp", "2")
    assert code == 0, err
    assert_same_image(result, obscura.read_exr(out))
    with pytest.raises(obscura.Error, match=r"--subdiv-edge: the scene was refined for camera '' at 64x48"):
        obscura.render(scene, res=(32, 24))


def test_environment_keywords_equal_cli(scene, tmp_path):
    # environment= and its options light the render exactly as the CLI's flags.
    sky = str(tmp_path / "sky.exr")
    code, err = cli("sky", "overcast", "--res", "32x16", "-o", sky)
    assert code == 0, err
    result = obscura.render(scene, "ao", None, spp=2, res=(32, 18), environment=sky,
                            environment_rotation=30.0, environment_strength=2.0)
    cli_exr = str(tmp_path / "cli.exr")
    code, err = cli("render", SCENE, "-o", cli_exr, "-q", "-i", "ao", "--spp", "2", "--res", "32x18",
                    "--environment", sky, "--environment-rotation", "30", "--environment-strength", "2")
    assert code == 0, err
    assert_same_image(result, obscura.read_exr(cli_exr))
    assert "lighting.R" in result.channel_names
    assert result.header["obscura:environment"] == sky
    assert result.header["obscura:environmentRotation"] == "30"


def test_write_refuses_outputs_like_the_cli(tmp_path):
    # Result.write and checkpoint_file go through the CLI's output checks: an
    # output equal to the scene or to a file it names (here its external
    # buffer) is refused before anything is written, as are a name too long
    # for the temporary beside it and an extension that is not the format.
    # They used to check the scene alone.
    data = struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0)
    (tmp_path / "tri.bin").write_bytes(data)
    gltf = tmp_path / "tri.gltf"
    gltf.write_text(json.dumps({
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "buffers": [{"byteLength": len(data), "uri": "tri.bin"}],
        "bufferViews": [{"buffer": 0, "byteLength": len(data)}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 0]}]}))
    scene_bytes = gltf.read_bytes()
    result = obscura.render(obscura.Scene(str(gltf)), "ao", spp=1, res=(8, 8))
    binary = str(tmp_path / "tri.bin")
    good = str(tmp_path / "ok.exr")
    cases = [
        (dict(path=binary), ["-o", binary]),
        (dict(path=good, preview=binary), ["-o", good, "--preview", binary]),
        (dict(path=str(gltf)), ["-o", str(gltf)]),
        (dict(path=str(tmp_path / ("n" * 246 + ".exr"))), ["-o", str(tmp_path / ("n" * 246 + ".exr"))]),
        (dict(path=str(tmp_path / "x.tif")), ["-o", str(tmp_path / "x.tif")]),
    ]
    for kwargs, flags in cases:
        with pytest.raises(obscura.Error) as e:
            result.write(**kwargs)
        assert str(e.value) == cli_error("render", str(gltf), "-q", "--res", "8x8", "--spp", "1", *flags)
    assert "is the same file as " + str(gltf) + " buffers[0] " + binary in cli_error(
        "render", str(gltf), "-q", "-o", binary)
    with pytest.raises(obscura.Error, match=r"checkpoint_file .*tri.bin: is the same file as .*buffers\[0\]"):
        obscura.render(obscura.Scene(str(gltf)), "ao", spp=1, res=(8, 8), checkpoint=0, checkpoint_file=binary)
    assert (tmp_path / "tri.bin").read_bytes() == data
    assert gltf.read_bytes() == scene_bytes
    assert not (tmp_path / "ok.exr").exists()
    assert sorted(os.listdir(tmp_path)) == ["tri.bin", "tri.gltf"]
