"""The Python module against the command line: the same renders bit for bit, every layer, the
errors, Ctrl-C, the GIL. Run by scripts/test-python.sh (CI), which builds the module and
names the command line's binary in LIGHTSPLIT."""

import _thread
import json
import os
import signal
import subprocess
import threading
import time
from pathlib import Path

import numpy as np
import OpenEXR
import pytest

import lightsplit

ROOT = Path(__file__).resolve().parents[2]
CORNELL = ROOT / "scenes" / "cornell.toml"


def binary() -> str:
    found = os.environ.get("LIGHTSPLIT")
    if found:
        return found
    for profile in ("ci", "release", "debug"):
        path = ROOT / "target" / profile / "lightsplit"
        if path.exists():
            return str(path)
    pytest.skip("no lightsplit binary: set LIGHTSPLIT")


def cli(*args) -> subprocess.CompletedProcess:
    return subprocess.run([binary(), *map(str, args)], check=True, capture_output=True, text=True)


def exr_channels(path) -> dict:
    """Every channel of an EXR as a height x width float32 array."""
    with OpenEXR.File(str(path), separate_channels=True) as f:
        return {name: np.asarray(ch.pixels, dtype=np.float32) for name, ch in f.channels().items()}


def module_channels(render) -> dict:
    """The render's arrays under the EXR's channel names."""
    out = {c: render.image[:, :, i] for i, c in enumerate("RGB")}
    for name, array in render.layers.items():
        for i, channel in enumerate(render.channels[name]):
            full = channel if name == channel else f"{name}.{channel}"
            out[full] = array[:, :, i]
    return out


@pytest.mark.parametrize("flags", [[], ["--denoise"], ["--filter", "box3"]])
def test_every_layer_equals_the_command_lines_exr_bit_for_bit(tmp_path, flags):
    out = tmp_path / "cli.exr"
    cli("render", CORNELL, "--width", 32, "--height", 24, "--spp", 8, "--seed", 3, "-o", out, *flags)
    scene = lightsplit.load(CORNELL, width=32, height=24)
    render = scene.render(
        spp=8,
        seed=3,
        denoise="--denoise" in flags,
        filter=flags[1] if "--filter" in flags else None,
    )
    want = exr_channels(out)
    got = module_channels(render)
    assert sorted(got) == sorted(want), "the same layers"
    for name, values in want.items():
        assert got[name].shape == (24, 32)
        assert got[name].dtype == np.float32
        assert np.array_equal(got[name].view(np.uint32), values.view(np.uint32)), name
    # And the module's own EXR is the command line's.
    saved = tmp_path / "module.exr"
    render.save(saved)
    again = exr_channels(saved)
    assert all(np.array_equal(again[n].view(np.uint32), v.view(np.uint32)) for n, v in want.items())


def test_aovs_light_groups_and_cryptomatte_equal_the_command_lines_bit_for_bit(tmp_path):
    gallery = ROOT / "scenes" / "paper-gallery.toml"
    out = tmp_path / "cli.exr"
    cli("render", gallery, "--width", 32, "--height", 24, "--spp", 4, "--seed", 2, "-o", out,
        "--aov", "diffuse_indirect", "--aov", "all=C.*L", "--light-groups", "--cryptomatte")
    render = lightsplit.load(gallery, width=32, height=24).render(
        spp=4, seed=2, aovs=["diffuse_indirect", "all=C.*L"], light_groups=True, cryptomatte=True
    )
    want = exr_channels(out)
    got = module_channels(render)
    assert sorted(got) == sorted(want), "the same layers"
    for name in ("diffuse_indirect", "all", "CryptoObject00", "CryptoMaterial02"):
        assert name in render.layers, name
    assert any(n.startswith("group_") for n in render.layers), "a light group's layer"
    for name, values in want.items():
        assert np.array_equal(got[name].view(np.uint32), values.view(np.uint32)), name
    with OpenEXR.File(str(out)) as f:
        header = {k: v for k, v in f.header().items() if k.startswith("cryptomatte/")}
    assert header and render.cryptomatte == header
    with pytest.raises(ValueError, match="AOV name `1x`"):
        lightsplit.load(gallery).render(spp=1, aovs=["1x=C.*L"])


def test_the_named_layers_are_there_with_their_shapes():
    render = lightsplit.load(CORNELL, width=16, height=16).render(spp=2)
    layers = render.layers
    for name, channels in [("direct", 3), ("indirect", 3), ("albedo", 3), ("normal", 3), ("depth", 1),
                           ("objectid", 2), ("indirect_variance", 1), ("raw", 3)]:
        assert layers[name].shape == (16, 16, channels), name
    assert render.channels["objectid"] == ["ID", "coverage"]
    # The components add up to the beauty (up to rounding).
    total = sum(layers[c] for c in ("emitted", "direct", "caustic", "indirect"))
    assert np.allclose(total, layers["raw"], rtol=1e-5, atol=1e-6)
    assert np.array_equal(render.image, layers["raw"]), "unfiltered: the final image is the beauty"


def test_scene_settings_and_camera_change_the_render():
    scene = lightsplit.load(CORNELL)
    assert (scene.width, scene.height, scene.spp, scene.seed) == (256, 256, 64, 0)
    scene.width, scene.height = 20, 10
    before = scene.render(spp=1).image
    assert before.shape == (10, 20, 3)
    camera = scene.camera
    scene.set_camera(position=[camera["position"][0] + 100, camera["position"][1], camera["position"][2]])
    assert scene.camera["position"][0] == camera["position"][0] + 100
    assert not np.array_equal(scene.render(spp=1).image, before), "the camera moved"
    assert len(scene.objects) == 8 and len(scene.materials) == 4
    with pytest.raises(ValueError, match="fov"):
        scene.set_camera(fov=0)


def test_bad_input_raises_value_error_naming_file_and_line(tmp_path):
    with pytest.raises(ValueError, match="nothing.toml"):
        lightsplit.load(tmp_path / "nothing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[camera]\nposition = [0, 0, 0]\nfov = 'wide'\n")
    with pytest.raises(ValueError, match=r"bad\.toml:3"):
        lightsplit.load(bad)
    scene = lightsplit.load(CORNELL, width=8, height=8)
    with pytest.raises(ValueError, match="accel"):
        scene.render(accel="octree")
    with pytest.raises(ValueError, match="sampler"):
        scene.render(sampler="halton")
    with pytest.raises(ValueError, match="threads"):
        scene.render(threads=0)
    with pytest.raises(ValueError):
        scene.render(filter="box4")
    with pytest.raises(TypeError, match="overrides"):
        lightsplit.load(CORNELL, exposure=2)


def test_threads_and_progress():
    scene = lightsplit.load(CORNELL, width=16, height=16)
    seen = []
    render = scene.render(spp=16, threads=1, progress=lambda done, total: seen.append((done, total)))
    assert render.stats["threads"] == 1
    assert seen and seen[-1] == (16 * 16 * 16, 16 * 16 * 16), "the last report: all samples done"
    assert all(a[0] <= b[0] for a, b in zip(seen, seen[1:])), "progress never goes back"
    # One thread or two: the same image.
    assert np.array_equal(render.image, scene.render(spp=16, threads=2).image)


def test_ctrl_c_stops_after_a_pass_and_keeps_the_samples():
    scene = lightsplit.load(CORNELL, width=64, height=64)
    total = 64 * 64 * 1024

    def interrupt(done, _total):
        if done > 0:
            _thread.interrupt_main()  # as Ctrl-C: the signal reaches the main thread

    # Python's own Ctrl-C handler, whatever this process inherited: a shell starts a background
    # job with SIGINT ignored, and then Python installs none and interrupt_main does nothing.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt) as caught:
            scene.render(spp=1024, progress=interrupt)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert isinstance(caught.value, lightsplit.Interrupted)
    render = caught.value.render
    assert render.stats["interrupted"]
    assert 0 < render.stats["samples"] < total
    assert render.stats["min_spp"] >= 1, "every pixel keeps the passes it finished"
    assert np.isfinite(render.image).all() and render.image.max() > 0


def test_the_gil_is_released_while_rendering():
    scene = lightsplit.load(CORNELL, width=64, height=64)
    ticks = []
    running = threading.Event()

    def count():
        running.set()
        while running.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.001)

    t = threading.Thread(target=count)
    t.start()
    running.wait()
    start = time.perf_counter()
    render = scene.render(spp=256, threads=1)
    end = time.perf_counter()
    running.clear()
    t.join()
    during = [x for x in ticks if start < x < end]
    # A thread starved of the GIL would tick once or not at all; 1 ms sleeps tick hundreds of
    # times over a render of a tenth of a second or more.
    assert render.stats["seconds"] > 0.05
    assert len(during) > 10 * render.stats["seconds"], (len(during), render.stats["seconds"])


def test_filter_compare_and_merge_equal_the_command_line(tmp_path):
    scene = lightsplit.load(CORNELL, width=32, height=32)
    plain = scene.render(spp=8, seed=1)
    denoised = scene.render(spp=8, seed=1, denoise=True)
    refiltered = lightsplit.filter(plain, denoise=True)
    assert np.array_equal(refiltered.image.view(np.uint32), denoised.image.view(np.uint32))
    assert refiltered.filter and "atrous" in refiltered.filter
    # compare: the command line's numbers.
    reference = scene.render(spp=64, seed=2)
    plain.save(tmp_path / "a.exr")
    reference.save(tmp_path / "b.exr")
    want = json.loads(cli("compare", "--json", tmp_path / "a.exr", tmp_path / "b.exr").stdout)
    got = lightsplit.compare(plain, reference)
    for key in ("sse", "rmse", "relmse", "rmse_trimmed", "relmse_trimmed"):
        assert got[key] == want[key], key
    assert lightsplit.compare(tmp_path / "a.exr", reference.image)["rmse"] == want["rmse"]
    with pytest.raises(ValueError, match="differ in size"):
        lightsplit.compare(plain, np.zeros((4, 4, 3), np.float32))
    # merge: the command line's merge of the same parts, bit for bit, and the whole render's
    # samples (summed in another order: equal up to rounding).
    parts = [tmp_path / f"p{i}.exr" for i in range(2)]
    for i, part in enumerate(parts):
        cli("render", CORNELL, "--width", 32, "--height", 32, "--spp", 8, "--seed", 1,
            "--part", f"{i}/2", "-o", part)
    cli("merge", *parts, "-o", tmp_path / "merged.exr")
    merged = lightsplit.merge(parts)
    want = exr_channels(tmp_path / "merged.exr")
    got = module_channels(merged)
    assert sorted(got) == sorted(want)
    assert all(np.array_equal(got[n].view(np.uint32), v.view(np.uint32)) for n, v in want.items())
    assert np.allclose(merged.layers["indirect"], plain.layers["indirect"], rtol=1e-5, atol=1e-7)
    with pytest.raises(ValueError, match="missing part 1/2"):
        lightsplit.merge(parts[:1])
    # With allow_missing, the part there is: its samples alone, as the command line merges it.
    cli("merge", "--allow-missing", parts[0], "-o", tmp_path / "half.exr")
    half = lightsplit.merge(parts[:1], allow_missing=True)
    assert np.array_equal(half.image.view(np.uint32), np.dstack([exr_channels(tmp_path / "half.exr")[c] for c in "RGB"]).view(np.uint32))
    assert not np.array_equal(half.image, merged.image)


def test_parts_rendered_in_memory_merge_as_the_command_lines_part_files(tmp_path):
    files = [tmp_path / f"p{i}.exr" for i in range(3)]
    for i, path in enumerate(files):
        cli("render", CORNELL, "--width", 24, "--height", 16, "--spp", 9, "--seed", 4,
            "--part", f"{i}/3", "-o", path)
    cli("merge", *files, "-o", tmp_path / "merged.exr")
    want = exr_channels(tmp_path / "merged.exr")
    scene = lightsplit.load(CORNELL, width=24, height=16)
    parts = [scene.render(spp=9, seed=4, part=(i, 3)) for i in range(3)]
    assert [p.part for p in parts] == ["0/3", "1/3", "2/3"]
    assert "part 1/3" in repr(parts[1])

    def same(render):
        got = module_channels(render)
        return sorted(got) == sorted(want) and all(
            np.array_equal(got[n].view(np.uint32), v.view(np.uint32)) for n, v in want.items()
        )

    # In memory, in any order, and mixed with the command line's files: the same bits.
    merged = lightsplit.merge(parts[::-1])
    assert same(merged)
    stats = merged.stats
    assert (stats["samples"], stats["min_spp"], stats["max_spp"]) == (24 * 16 * 9, 9, 9)
    assert same(lightsplit.merge([parts[0], files[1], parts[2]]))
    # A part saved is a part file the command line merges.
    parts[1].save(tmp_path / "m1.exr")
    cli("merge", files[0], tmp_path / "m1.exr", files[2], "-o", tmp_path / "again.exr")
    assert all(
        np.array_equal(v.view(np.uint32), want[n].view(np.uint32))
        for n, v in exr_channels(tmp_path / "again.exr").items()
    )
    # The merge's checks, naming the parts.
    with pytest.raises(ValueError, match="missing part 2/3"):
        lightsplit.merge(parts[:2])
    with pytest.raises(ValueError, match="both part 1/3"):
        lightsplit.merge([parts[0], parts[1], files[1], parts[2]])
    other = scene.render(spp=9, seed=5, part="1/3")
    with pytest.raises(ValueError, match="different renders"):
        lightsplit.merge([parts[0], other, parts[2]])
    with pytest.raises(ValueError, match="must be a part"):
        lightsplit.merge([scene.render(spp=1)])
    # A part is never filtered, and is saved as its part file only.
    with pytest.raises(ValueError, match="never filtered"):
        scene.render(spp=9, part=(0, 3), denoise=True)
    with pytest.raises(ValueError, match="part file"):
        parts[0].save(tmp_path / "p.png")
    with pytest.raises(ValueError, match="--part"):
        scene.render(spp=9, part=(3, 3))


def test_filter_takes_the_layers_as_arrays():
    render = lightsplit.load(CORNELL, width=32, height=24).render(spp=8, seed=5)
    layers = {k: v for k, v in render.layers.items() if k != "indirect_filtered"}
    # The layers as they are: the same filter, the same bits, as filtering the render.
    want = lightsplit.filter(render, denoise=True).image
    got = lightsplit.filter(layers, denoise=True).image
    assert np.array_equal(got.view(np.uint32), want.view(np.uint32))
    # Changed layers are what is filtered: the indirect light doubled (in the beauty too), box3
    # (linear) on it gives twice the filtered indirect light, and the final image is the other
    # components plus it.
    changed = dict(layers, indirect=layers["indirect"] * 2, raw=layers["raw"] + layers["indirect"])
    plain = lightsplit.filter(layers, "box3", "indirect")
    boxed = lightsplit.filter(changed, "box3", "indirect")
    assert np.allclose(boxed.layers["indirect_filtered"], 2 * plain.layers["indirect_filtered"], rtol=1e-5, atol=1e-7)
    others = changed["emitted"] + changed["direct"] + changed["caustic"]
    assert np.allclose(boxed.image, others + boxed.layers["indirect_filtered"], rtol=1e-5, atol=1e-6)
    with pytest.raises(ValueError, match="not a layer"):
        lightsplit.filter(dict(layers, shadow=layers["raw"]), denoise=True)
    with pytest.raises(ValueError, match="channels"):
        lightsplit.filter(dict(layers, depth=layers["raw"]), denoise=True)


def test_save_and_show(tmp_path):
    render = lightsplit.load(CORNELL, width=16, height=16).render(spp=2)
    png = render._repr_png_()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    render.save(tmp_path / "x.png", exposure=1.0)
    assert (tmp_path / "x.png").read_bytes()[:4] == b"\x89PNG"
    with pytest.raises(ValueError, match="exposure"):
        render.save(tmp_path / "x.exr", exposure=1.0)
    render.save(tmp_path / "y.exr")
    back = lightsplit.read(tmp_path / "y.exr")
    assert np.array_equal(back.image, render.image)
    # Another compression: the same channels, and the header says which; ZIP by default.
    render.save(tmp_path / "rle.exr", compression="rle")
    with OpenEXR.File(str(tmp_path / "rle.exr")) as f:
        assert f.header()["compression"] == OpenEXR.RLE_COMPRESSION
    with OpenEXR.File(str(tmp_path / "y.exr")) as f:
        assert f.header()["compression"] == OpenEXR.ZIP_COMPRESSION
    a, b = exr_channels(tmp_path / "rle.exr"), exr_channels(tmp_path / "y.exr")
    assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)
    with pytest.raises(ValueError, match="lzw"):
        render.save(tmp_path / "z.exr", compression="lzw")
    with pytest.raises(ValueError, match="exr only"):
        render.save(tmp_path / "z.png", compression="rle")
    assert not (tmp_path / "z.exr").exists() and not (tmp_path / "z.png").exists()
    assert "Render(16x16" in repr(render)
