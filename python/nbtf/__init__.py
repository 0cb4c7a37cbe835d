"""nbtf from Python: compressed neural BTF materials (.nbtf files) with numpy in and numpy out.

    import nbtf
    with nbtf.open("wool.nbtf") as m:
        rgb = m.query(texel=(12, 40), light=(30, 60), view=(45, 180))   # float32 (3,), linear RGB
        img = m.decode_image(light=(30, 60), view=(0, 0))               # float32 (H, W, 3)
    stack = nbtf.load_stack("data/wool")                                # images [N, H, W, 3], lights, views
    summary = nbtf.compress("data/wool", "wool.nbtf", clusters=500, time_budget=600)
    report = nbtf.evaluate("wool.nbtf", "data/wool")

`open`, `load_stack` and queries use the decoder and the stack loader only (the extension
_nbtf, no libtorch); `compress` and `evaluate` import the training side (_nbtf_train) when
first called. Errors: OSError (FileNotFoundError, PermissionError, ...) for files that cannot
be reached, read or written; ValueError for arguments and data, with the messages of the
`nbtf` command line. The reference is docs/python.md.
"""

import difflib as _difflib
import json as _json
import os as _os
import re as _re

import numpy as _np

from . import _nbtf

__all__ = ["Material", "Stack", "open", "load_stack", "compress", "evaluate", "set_threads", "threads"]
__version__ = _nbtf.__version__

_threads = 0  # as --threads: 0 = every core
_train_module = None


def _train():
    """The training side (libtorch), imported on first use."""
    global _train_module
    if _train_module is None:
        from . import _nbtf_train

        _nbtf_train.set_threads(_threads)
        _train_module = _nbtf_train
    return _train_module


def set_threads(threads):
    """Worker threads for decoding, loading, compressing and evaluating: what the command
    line's --threads sets (0 = every core, the default; more than the cores are capped)."""
    global _threads
    if isinstance(threads, bool) or not isinstance(threads, (int, _np.integer)):
        raise ValueError(f"threads: expected an integer, got {threads!r}")
    threads = int(threads)
    if threads < 0:
        raise ValueError(f"--threads must be >= 0, got {threads}")
    cores = _os.cpu_count() or 0
    if cores and threads > cores:
        import warnings

        warnings.warn(f"threads {threads} is more than the {cores} cores of this machine; using {cores}", stacklevel=2)
        threads = cores
    _threads = threads
    _nbtf.set_threads(threads)
    if _train_module is not None:
        _train_module.set_threads(threads)


def threads():
    """The number of worker threads the library uses now."""
    return _nbtf.threads()


def _path(value, what):
    try:
        return _os.fspath(value)
    except TypeError:
        raise TypeError(f"{what}: expected a path (str or os.PathLike), got {type(value).__name__}") from None


def _numbers(value, what, kinds="iuf"):
    try:
        a = _np.asarray(value)
    except Exception as e:  # ragged sequences and the like
        raise ValueError(f"{what}: not an array of numbers ({e})") from None
    if a.dtype.kind not in kinds:
        raise ValueError(f"{what}: expected {'integers' if kinds == 'iu' else 'numbers'}, got dtype {a.dtype}")
    return a


def _crop_text(crop):
    """(x, y, w, h) -> "X,Y,W,H", the --crop text (checked by the library, as on the command line)."""
    if isinstance(crop, str):
        return crop
    c = _numbers(crop, "crop", "iu")
    if c.shape != (4,):
        raise ValueError(f"crop: expected (x, y, width, height), got {crop!r}")
    return ",".join(str(int(v)) for v in c)


def _direction_array(value, what):
    a = _numbers(value, what)
    if a.ndim == 0 or a.shape[-1] not in (2, 3):
        raise ValueError(
            f"{what}: expected (theta, phi) in degrees (last axis 2) or unit vectors (x, y, z) in the local frame "
            f"(last axis 3), got shape {a.shape}"
        )
    return a


def _flat(a, shape, dtype):
    """a broadcast to shape + (k,), as a C-contiguous (n, k) array of dtype."""
    k = a.shape[-1]
    return _np.ascontiguousarray(_np.broadcast_to(a, shape + (k,)).reshape(-1, k), dtype=dtype)


class Material:
    """An open .nbtf file (nbtf.open). Closing it (close(), or leaving a `with` block) frees
    the decoder; every use after that raises ValueError."""

    def __init__(self, path, isa="auto"):
        self._m = _nbtf.Material(_path(path, "path"), isa)
        self._info = None

    # ---- The material
    @property
    def path(self):
        return self._m.path

    @property
    def closed(self):
        return self._m.closed

    @property
    def info(self):
        """The dictionary `nbtf info --json FILE` prints."""
        self._m.width  # raises on a closed material
        if self._info is None:
            self._info = _json.loads(self._m.info_json)
        return self._info

    @property
    def sizes(self):
        """The parts of Table 1 in bytes: decoder, latents, ids (PCA files: pca_mean, pca_basis,
        pca_coefficients), total, raw_float32, file, ratio (raw_float32 / total), and more."""
        self._m.width
        return self._m.sizes()

    width = property(lambda self: self._m.width, doc="Texels across")
    height = property(lambda self: self._m.height, doc="Texels down")
    alpha = property(lambda self: self._m.alpha, doc="The material's scale: linear RGB = normalized output x alpha")
    lights = property(lambda self: self._m.lights, doc="Measured light directions, (L, 2) theta, phi in degrees")
    views = property(lambda self: self._m.views, doc="Measured view directions, (V, 2) theta, phi in degrees")
    isa = property(lambda self: self._m.isa, doc="The decoder's kernels: portable, avx2+fma or avx512")

    # ---- Decoding
    def _check_texels(self, xy):
        """The decoder's own message for a texel outside the material, with the value given (one
        beyond the 32-bit range the decoder takes is named as given, not as clipped)."""
        w, h = self.width, self.height
        outside = (xy[:, 0] < 0) | (xy[:, 0] >= w) | (xy[:, 1] < 0) | (xy[:, 1] >= h)
        if outside.any():
            i = int(_np.argmax(outside))
            x, y = (int(v) for v in xy[i])
            prefix = f"query {i}: " if len(xy) > 1 else ""
            raise ValueError(f"{prefix}texel ({x}, {y}) is outside the {w} x {h} material (0 <= x < {w}, 0 <= y < {h})")

    def query(self, texel=None, uv=None, *, light, view, normalized=False):
        """Decoded RGB at texels and directions; float32 (..., 3), linear RGB (sRGB primaries),
        or the decoder's own output (linear / alpha) with normalized=True (`nbtf query
        --normalized`).

        Give exactly one of
          texel  integer (..., 2) arrays of (x, y): 0 <= x < width, 0 <= y < height, y = 0 the top row
          uv     (..., 2) texture coordinates (u, v); they wrap (the texture tiles)
        and light, view as either
          (..., 2) (theta, phi) in degrees: `nbtf query`'s path, bit for bit, or
          (..., 3) unit vectors (x, y, z) in the local frame, z the surface normal (normalized here).
        Both directions take the same form. The leading axes of all three broadcast like numpy's.
        """
        if (texel is None) == (uv is None):
            raise ValueError("give exactly one of texel= (x, y) and uv= (u, v)")
        if texel is not None:
            pos = _numbers(texel, "texel")
            if pos.dtype.kind == "f":
                raise ValueError(f"texel: expected integer (x, y), got dtype {pos.dtype}; for texture coordinates (u, v) use uv=")
            what = "texel"
        else:
            pos = _numbers(uv, "uv")
            what = "uv"
        if pos.ndim == 0 or pos.shape[-1] != 2:
            raise ValueError(f"{what}: expected (..., 2) arrays of ({'x, y' if what == 'texel' else 'u, v'}), got shape {pos.shape}")
        light = _direction_array(light, "light")
        view = _direction_array(view, "view")
        if light.shape[-1] != view.shape[-1]:
            raise ValueError(
                "light and view: give both as (theta, phi) angles or both as unit vectors, got last axes "
                f"{light.shape[-1]} and {view.shape[-1]}"
            )
        try:
            shape = _np.broadcast_shapes(pos.shape[:-1], light.shape[:-1], view.shape[:-1])
        except ValueError:
            raise ValueError(
                f"{what}, light and view do not broadcast together: leading shapes {pos.shape[:-1]}, "
                f"{light.shape[:-1]}, {view.shape[:-1]}"
            ) from None
        if what == "texel":
            self._check_texels(_np.broadcast_to(pos, shape + (2,)).reshape(-1, 2))
            t, u = _flat(pos, shape, _np.int32), None
        else:
            t, u = None, _flat(pos, shape, _np.float32)
        if light.shape[-1] == 2:
            out = self._m.query_angles(t, u, _flat(light, shape, _np.float64), _flat(view, shape, _np.float64), bool(normalized))
        else:
            out = self._m.query_vectors(t, u, _flat(light, shape, _np.float32), _flat(view, shape, _np.float32), bool(normalized))
        return out.reshape(shape + (3,))

    def decode_image(self, light, view, size=None, normalized=False):
        """The whole material at one (light, view), measured or not: float32 (H, W, 3), top row
        first (what `nbtf decode --light --view` writes, before its 8-bit or half-float file).
        light, view: (theta, phi) in degrees or a unit vector (x, y, z). size: (width, height),
        larger than the material to tile it (default: the material's size)."""
        light = _direction_array(light, "light")
        view = _direction_array(view, "view")
        for name, d in (("light", light), ("view", view)):
            if d.ndim != 1:
                raise ValueError(f"{name}: decode_image takes one direction, got shape {d.shape}")
        if size is None:
            width = height = 0
        else:
            s = _numbers(size, "size", "iu")
            if s.shape != (2,):
                raise ValueError(f"size: expected (width, height), got {size!r}")
            width, height = int(s[0]), int(s[1])
            if width < 1 or height < 1:
                raise ValueError(f"size: expected (width, height), each at least 1, got ({width}, {height})")
        return self._m.decode_image(light.astype(_np.float64).tolist(), view.astype(_np.float64).tolist(), width, height,
                                    bool(normalized))

    # ---- Lifetime
    def close(self):
        self._m.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    def __repr__(self):
        if self.closed:
            return f"<nbtf.Material {self.path!r} (closed)>"
        i = self.info
        return (f"<nbtf.Material {self.path!r}: {i['method']}, {self.width} x {self.height} texels, "
                f"{i['lights']} x {i['views']} directions, format {i['format_version']}>")


def open(path, isa="auto"):  # noqa: A001 (the name the issue asks for; builtins.open stays reachable as such)
    """Opens a .nbtf file: a Material. isa: the decoder's kernels (auto, portable, avx2, avx512),
    as `nbtf query --isa`."""
    return Material(path, isa)


class Stack:
    """An image stack as nbtf.load_stack returns it.

    images   [images, H, W, 3]: float32 linear RGB, or (linear=False) the stored samples
             without a copy: uint8 sRGB codes or float16 linear values, read-only
    lights   (L, 2) and views (V, 2) directions, theta and phi in degrees; image i is
             light i // V, view i % V
    layout, samples (as `nbtf info` names them: "8-bit sRGB", "half float (linear)"), source,
    image_size (on disk), crop (x, y, w, h) or None, computed (a UBO2014 file kept factorized)
    """

    def __init__(self, d):
        self.images = d["images"]
        self.lights = d["lights"]
        self.views = d["views"]
        self.layout = d["layout"]
        self.samples = d["samples"]
        self.source = d["source"]
        self.image_size = d["image_size"]
        self.crop = d["crop"]
        self.computed = d["computed"]

    def __iter__(self):  # images, lights, views = nbtf.load_stack(...)
        return iter((self.images, self.lights, self.views))

    def __repr__(self):
        n, h, w = self.images.shape[:3]
        return f"<nbtf.Stack {self.source!r}: {n} images of {w} x {h}, {self.layout}, {self.images.dtype}>"


def load_stack(path, crop=None, layout=None, linear=True, memory_limit=None, progress=False, quiet=False):
    """Loads an image stack the way `nbtf compress` reads it: a UBO2003 or UTIA folder, or a
    UBO2014 .btf file. crop: (x, y, w, h) applied while loading; layout: "ubo2003", "utia" or
    "ubo2014" (default: detected). linear=False gives the stored samples without a copy.
    A stack whose memory (stored + the float32 copy) is above memory_limit ("16G", "800M",
    bytes; default 75% of physical memory) is refused before loading, naming what to crop.
    progress: False (none), None (the command line's bars on the terminal) or a callable
    taking a dict (label, done, total, seconds, status, final)."""
    path = _path(path, "path")
    crop_text = "" if crop is None else _crop_text(crop)
    layout_text = "" if layout is None else str(layout)
    limit = "" if memory_limit is None else str(memory_limit)
    callback = None if progress is None or progress is False else progress
    if callback is not None and not callable(callback):
        raise ValueError(f"progress: expected a callable, None or False, got {progress!r}")
    d = _nbtf.load_stack(path, crop_text, layout_text, bool(linear), limit, callback, bool(quiet) or progress is False)
    return Stack(d)


_NOT_OPTIONS = {"input", "output", "o", "help", "h", "q"}


def _compress_keywords():
    """compress's keywords: the long options of `nbtf compress`, '-' written '_'."""
    return {name.replace("-", "_") for name in _train().compress_options()} - _NOT_OPTIONS


def _python_names(message, keywords):
    """A message of the command line's option set with its options named as compress's
    keywords ("--time-budget" -> "time_budget=")."""
    def name(m):
        keyword = m.group(1).replace("-", "_")
        return keyword + "=" if keyword in keywords else m.group(0)
    return _re.sub(r"--([a-z][a-z0-9-]*)", name, message)


def compress(source, out, *, progress=None, **options):
    """Compresses a stack (folder or UBO2014 .btf) into the .nbtf file `out`; returns the
    summary `nbtf compress --stats-json` writes, as a dict.

    The options are the command line's, with '_' for '-': clusters=500, time_budget=600,
    config="compact", seed=1, holdout=0.1, epochs=..., method="pca", components=..., crop=(x, y,
    w, h), layout=..., adaptive=True, target_rmse=..., memory_limit="8G", resume=True,
    stats_json=..., save_encoder=..., threads=..., quiet=True, ... They are parsed by the very
    option set of `nbtf compress`, so every name, default and check is the command line's;
    messages name them as keywords (time_budget=), and an unknown keyword raises TypeError, as
    for any Python function. True turns a flag on; None or False leaves an option out.

    progress: None (the command line's text bars on the terminal; quiet=True: none) or a
    callable taking a dict (label, done, total, seconds, status, final). An exception in the
    callback, or Ctrl-C, stops training after a checkpoint and raises (KeyboardInterrupt names
    the checkpoint: resume=True continues from it)."""
    args = [_path(source, "source"), "-o", _path(out, "out")]
    keywords = _compress_keywords()
    for name, value in options.items():
        if name in _NOT_OPTIONS:
            raise TypeError(f"compress() got an unexpected keyword argument '{name}' (the source and the output are "
                            "its first two arguments)")
        if name not in keywords:
            close = _difflib.get_close_matches(name, sorted(keywords), n=1)
            raise TypeError(f"compress() got an unexpected keyword argument '{name}'" +
                            (f"; did you mean '{close[0]}'?" if close else ""))
        flag = "--" + name.replace("_", "-")
        if value is None or value is False:
            continue
        if value is True:
            args.append(flag)
            continue
        if name == "crop":
            value = _crop_text(value)
        elif isinstance(value, _os.PathLike):
            value = _os.fspath(value)
        args.append(f"{flag}={value}")
    if "threads" not in options and _threads:
        args.append(f"--threads={_threads}")
    if progress is not None and not callable(progress):
        raise ValueError(f"progress: expected a callable or None, got {progress!r}")
    try:
        text = _train().compress(args, progress)
    except ValueError as e:
        raise ValueError(_python_names(str(e), keywords)) from None
    return None if text is None else _json.loads(text)


def evaluate(file, reference, *, output=None, crop=None, layout=None, blur_images=8, force=False,
             render_compare=None, progress=None, quiet=False):
    """Compares a .nbtf file with the stack it was made from (`nbtf eval`); returns report.json
    as a dict. output: also write the report folder (report.md, .html, .json, figures).
    crop, layout: of the reference (default: the file's). force: evaluate a reference that does
    not match the file's source fingerprint (the report says so). progress: as for compress."""
    if progress is not None and not callable(progress):
        raise ValueError(f"progress: expected a callable or None, got {progress!r}")
    if isinstance(blur_images, bool) or not isinstance(blur_images, (int, _np.integer)):
        raise ValueError(f"blur_images: expected an integer, got {blur_images!r}")
    text = _train().evaluate(
        _path(file, "file"),
        _path(reference, "reference"),
        "" if output is None else _path(output, "output"),
        "" if crop is None else _crop_text(crop),
        "" if layout is None else str(layout),
        int(blur_images),
        bool(force),
        "" if render_compare is None else _path(render_compare, "render_compare"),
        progress,
        bool(quiet),
        _threads,
    )
    return _json.loads(text)
