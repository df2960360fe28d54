"""lightsplit as a Python module: render a scene, get every light-path component as a NumPy
array, filter, compare, merge parts, without files in between.

    import lightsplit
    scene = lightsplit.load("scenes/cornell.toml", width=256, height=256)
    render = scene.render(spp=64, denoise=True)
    render.image                 # height x width x 3, float32: the final image
    render.layers["indirect"]    # the indirect diffuse light, L_rdd
    lightsplit.compare(render, reference)["rmse"]

The render runs in Rust without the GIL, through the same code and the same options as
`lightsplit render`; its arrays hold the values the command line's EXR holds, bit for bit.
"""

from __future__ import annotations

import os
import tempfile
from typing import Callable, Optional, Sequence, Tuple, Union

import numpy as np

from . import _native

__version__: str = _native.__version__
__all__ = ["load", "read", "merge", "filter", "compare", "Scene", "Render", "Interrupted"]


class Interrupted(KeyboardInterrupt):
    """Ctrl-C stopped a render at the end of a pass: `render` holds the samples it took, as the
    command line keeps them in its part file."""

    def __init__(self, render: "Render"):
        super().__init__("the render was interrupted; its samples are in .render")
        self.render = render


class Render:
    """A finished render: `image`, `layers`, `stats`, `save`. Shows as its image in a
    notebook."""

    def __init__(self, native: "_native.Render"):
        self._native = native
        self._image: Optional[np.ndarray] = None
        self._layers: Optional[dict] = None
        self._channels: Optional[dict] = None

    @property
    def width(self) -> int:
        return self._native.width

    @property
    def height(self) -> int:
        return self._native.height

    @property
    def image(self) -> np.ndarray:
        """The final image (filtered when a filter was on): height x width x 3, float32."""
        if self._image is None:
            self._image = self._native.image()
        return self._image

    def _load_layers(self) -> None:
        if self._layers is None:
            self._layers, self._channels = self._native.layers()

    @property
    def layers(self) -> dict:
        """Every other layer of the render's EXR, by name (`raw`, `emitted`, `direct`,
        `caustic`, `indirect`, `albedo`, `normal`, `depth`, `objectid`, `A`, the
        `*_variance` and `*_half` layers, `indirect_filtered`, the AOVs and light groups, the
        Cryptomatte ranks `CryptoObject00`...): height x width x channels, float32."""
        self._load_layers()
        return self._layers

    @property
    def channels(self) -> dict:
        """Each layer's channel names, in the order of its last axis (`objectid`: ID,
        coverage)."""
        self._load_layers()
        return self._channels

    @property
    def stats(self) -> dict:
        """seconds, build_seconds, filter_seconds, samples, rays, samples_per_second,
        rays_per_second, nonfinite_samples, min_spp, max_spp, interrupted, threads."""
        return self._native.stats

    @property
    def filter(self) -> Optional[str]:
        """The filter of the final image (`atrous:... on components`), or None."""
        return self._native.filter

    @property
    def cryptomatte(self) -> dict:
        """The Cryptomatte header attributes (`cryptomatte/<key>/name`, `.../manifest`, ...) of
        a render with `cryptomatte=True`, as its EXR holds them; empty otherwise."""
        return self._native.cryptomatte

    @property
    def part(self) -> Optional[str]:
        """The part of a render this is (`"i/n"`, rendered with `part=`), or None."""
        return self._native.part

    def save(
        self, path: Union[str, os.PathLike], exposure: float = 0.0, compression: Optional[str] = None
    ) -> None:
        """Writes the render as `lightsplit render` does: .exr (every layer, compressed as
        `compression` says: "zip", the default, "piz", "rle" or "none"), .png (the final image,
        `exposure` stops) or .hdr; a part (`part=`) as its part file, an .exr."""
        self._native.save(os.fspath(path), exposure, compression)

    def _repr_png_(self) -> bytes:
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "render.png")
            self.save(path)
            with open(path, "rb") as f:
                return f.read()

    def __repr__(self) -> str:
        s = self.stats
        return (
            f"Render({self.width}x{self.height}, {s['samples']} samples in {s['seconds']:.3f} s"
            + (f", {self.filter}" if self.filter else "")
            + (f", part {self.part}" if self.part else "")
            + (", interrupted" if s["interrupted"] else "")
            + ")"
        )


class Scene:
    """A loaded scene. `width`, `height`, `spp`, `seed` and `max_depth` may be changed, and the
    camera moved (`set_camera`), before rendering."""

    def __init__(self, native: "_native.Scene"):
        self._native = native

    path = property(lambda self: self._native.path, doc="The scene file.")
    objects = property(lambda self: self._native.objects, doc="Object names, by object ID.")
    materials = property(lambda self: self._native.materials, doc="Each material, described.")
    material_names = property(lambda self: self._native.material_names, doc="(index, name) pairs.")
    lights = property(lambda self: self._native.lights, doc="Each light, described.")
    notes = property(lambda self: self._native.notes, doc="What the loader approximated or skipped.")
    camera = property(lambda self: self._native.camera, doc="position, look_at, up, fov, orthographic, lens.")

    def _setting(name: str, doc: str):  # noqa: N805 (a property factory)
        return property(
            lambda self: getattr(self._native, name),
            lambda self, value: setattr(self._native, name, value),
            doc=doc,
        )

    width = _setting("width", "Image width in pixels.")
    height = _setting("height", "Image height in pixels.")
    spp = _setting("spp", "Samples per pixel.")
    seed = _setting("seed", "The seed of the render's numbers.")
    max_depth = _setting("max_depth", "The most bounces a path takes.")
    del _setting

    def set_camera(self, position=None, look_at=None, up=None, fov=None) -> None:
        """Moves the camera: each argument given replaces the camera's value."""
        self._native.set_camera(position, look_at, up, fov)

    def render(
        self,
        spp: Optional[int] = None,
        seed: Optional[int] = None,
        threads: Optional[int] = None,
        accel: str = "embree",
        sampler: Optional[str] = None,
        denoise: bool = False,
        filter: Optional[str] = None,
        filter_target: Optional[str] = None,
        part: Union[None, str, Tuple[int, int]] = None,
        aovs: Optional[Sequence[str]] = None,
        light_groups: bool = False,
        cryptomatte: bool = False,
        progress: Optional[Callable[[int, int], None]] = None,
    ) -> Render:
        """Renders the scene and returns the render, as `lightsplit render` would write it.

        spp, seed: over the scene's. threads: worker threads (default one per core). accel:
        "embree" or "bvh". sampler: "sobol" or "independent". denoise: `--denoise`. filter,
        filter_target: `--filter` and `--filter-target`. part: `(i, n)` or `"i/n"`, part i of n
        of each pixel's samples (`--part`): the render keeps its sums, `merge` adds parts up
        exactly and `save` writes its part file. aovs: light path expressions' layers,
        each `"NAME=EXPR"` or a built-in's name (`--aov`), over the scene file's. light_groups:
        a layer per light group (`--light-groups`). cryptomatte: the object and material
        mattes (`--cryptomatte`), their manifests in `Render.cryptomatte`. progress: called with (samples done, samples
        in all) about ten times a second, from this thread.

        Runs without the GIL. Ctrl-C stops it at the end of a pass and raises `Interrupted`,
        whose `render` keeps the samples taken."""
        if isinstance(part, tuple):
            if len(part) != 2:
                raise ValueError(f"part is (i, n) or \"i/n\"; this one is {part!r}")
            part = f"{part[0]}/{part[1]}"
        native, interrupted = self._native.render(
            spp, seed, threads, accel, sampler, denoise, filter, filter_target, part,
            None if aovs is None else list(aovs), light_groups, cryptomatte, progress,
        )
        render = Render(native)
        if interrupted:
            raise Interrupted(render)
        return render

    def __repr__(self) -> str:
        return repr(self._native)


def load(
    path: Union[str, os.PathLike],
    camera: Optional[str] = None,
    defines: Optional[dict] = None,
    **overrides,
) -> Scene:
    """Reads a scene file of any format the command line reads (lightsplit TOML, glTF, OBJ,
    PLY, Mitsuba XML). `camera`: a glTF file's camera (index or name); `defines`: a Mitsuba
    file's parameters; `overrides`: width, height, spp, seed, max_depth. Bad input raises
    ValueError with the command line's message (naming file and line)."""
    allowed = {"width", "height", "spp", "seed", "max_depth"}
    unknown = set(overrides) - allowed
    if unknown:
        raise TypeError(f"load() got unknown overrides {sorted(unknown)}; it takes {sorted(allowed)}")
    pairs = [(str(k), str(v)) for k, v in (defines or {}).items()]
    scene = Scene(_native.load(os.fspath(path), camera, pairs))
    for name, value in overrides.items():
        setattr(scene, name, value)
    return scene


def read(path: Union[str, os.PathLike]) -> Render:
    """An EXR that `lightsplit render` (or `merge`) wrote, as a render."""
    return Render(_native.read(os.fspath(path)))


def merge(parts, allow_missing: bool = False) -> Render:
    """Adds parts up into one render, as `lightsplit merge` does: renders of parts
    (`Scene.render(part=...)`) and part files (`lightsplit render --part I/N`), in any mix;
    `allow_missing` merges whichever parts there are (`--allow-missing`). Its `stats` count
    the samples merged (`samples`, `min_spp`, `max_spp`); the rest are the parts' own."""
    native = [p._native if isinstance(p, Render) else os.fspath(p) for p in parts]
    return Render(_native.merge(native, allow_missing))


def filter(render, setting: Optional[str] = None, target: Optional[str] = None, denoise: bool = False) -> Render:
    """`render` filtered again, as `lightsplit filter` does: `setting` a method as `--filter`
    takes it (`box3`, `atrous:passes=4`, ...), `target` as `--filter-target`, or `denoise`.
    `render` is a Render, or its layers as a dict of arrays by `Render.layers`' names (`raw`
    and the components, the guides, the variances, the halves; changed or made by the caller),
    which the film reads as it reads an EXR's layers."""
    if isinstance(render, dict):
        render = Render(_native.from_layers({str(k): np.ascontiguousarray(v, dtype=np.float32) for k, v in render.items()}))
    return Render(render._native.refilter(setting, target, denoise))


def _image(x) -> np.ndarray:
    if isinstance(x, Render):
        return x.image
    if isinstance(x, (str, os.PathLike)):
        return read(x).image
    a = np.asarray(x, dtype=np.float32)
    if a.ndim != 3 or a.shape[2] != 3:
        raise ValueError(f"an image is height x width x 3; this array is {a.shape}")
    return a


def compare(test, reference) -> dict:
    """The command line's `compare`: sse, rmse, relmse, rmse_trimmed, relmse_trimmed of `test`
    against `reference`, each a Render, an EXR's path or a height x width x 3 array."""
    return dict(_native.compare(_image(test), _image(reference)))
