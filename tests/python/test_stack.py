# nbtf.load_stack against the files on disk (a small UTIA stack of PNGs written here) and
# against what `nbtf info` reads of the same stack.
import json
import os
import struct
import zlib

import numpy as np
import pytest

import nbtf
from conftest import cli, cli_error, cli_errors, cli_json

LIGHTS = [(0, 0), (15, 0), (15, 60)]
VIEWS = [(0, 0), (30, 120)]
W, H = 5, 4


def write_png(path, rgb):
    """8-bit RGB PNG (rgb: H x W x 3 uint8), with zlib only."""
    h, w, _ = rgb.shape

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    raw = b"".join(b"\x00" + rgb[y].tobytes() for y in range(h))
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")
    path.write_bytes(png)


def angle(a):
    return f"{a:03d}"


@pytest.fixture(scope="module")
def png_stack(tmp_path_factory):
    """A UTIA stack of 3 lights x 2 views of 5 x 4 texels; returns (folder, images [6, H, W, 3])."""
    root = tmp_path_factory.mktemp("pngstack") / "stack"
    rng = np.random.default_rng(3)
    images = rng.integers(0, 256, (len(LIGHTS) * len(VIEWS), H, W, 3), dtype=np.uint8)
    for li, (tl, pl) in enumerate(LIGHTS):
        for vi, (tv, pv) in enumerate(VIEWS):
            folder = root / f"tv{angle(tv)}_pv{angle(pv)}"
            folder.mkdir(parents=True, exist_ok=True)
            write_png(folder / f"tl{angle(tl)}_pl{angle(pl)}_tv{angle(tv)}_pv{angle(pv)}.png",
                      images[li * len(VIEWS) + vi])
    return str(root), images


def srgb_to_linear(c):
    c = c / 255.0
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def test_stored_samples_without_a_copy(png_stack):
    path, images = png_stack
    s = nbtf.load_stack(path, linear=False)
    assert s.images.dtype == np.uint8 and s.images.shape == images.shape
    np.testing.assert_array_equal(s.images, images)
    assert not s.images.flags.writeable and not s.images.flags.owndata  # a view of the loader's storage
    assert s.samples == "8-bit sRGB" and s.layout == "utia" and s.crop is None and not s.computed
    np.testing.assert_array_equal(s.lights, LIGHTS)
    np.testing.assert_array_equal(s.views, VIEWS)
    images_, lights, views = s  # unpacks
    assert images_ is s.images


def test_linear_values_and_cli_description(png_stack):
    path, images = png_stack
    s = nbtf.load_stack(path)
    assert s.images.dtype == np.float32 and s.images.shape == images.shape
    np.testing.assert_allclose(s.images, srgb_to_linear(images.astype(np.float64)), rtol=1e-6, atol=1e-7)
    info = cli_json("info", path, "--json")
    assert [s.images.min(), s.images.max()] == [np.float32(v) for v in info["value_range_linear"]]
    assert (info["lights"], info["views"], info["width"], info["height"]) == (len(LIGHTS), len(VIEWS), W, H)
    dirs = cli_json("info", path, "--directions", "--json")
    np.testing.assert_array_equal(s.lights, [[d["theta_deg"], d["phi_deg"]] for d in dirs["lights"]])
    np.testing.assert_array_equal(s.views, [[d["theta_deg"], d["phi_deg"]] for d in dirs["views"]])


def test_crop_and_layout(png_stack):
    path, images = png_stack
    s = nbtf.load_stack(path, crop=(1, 2, 3, 2), layout="utia", linear=False)
    np.testing.assert_array_equal(s.images, images[:, 2:4, 1:4])
    assert s.crop == (1, 2, 3, 2) and s.image_size == (W, H)
    assert nbtf.load_stack(path, crop="1,2,3,2", linear=False).images.shape == (6, 2, 3, 3)


def test_load_errors_have_the_cli_messages(png_stack, tmp_path):
    path, _ = png_stack
    missing = str(tmp_path / "nothing")
    empty = tmp_path / "empty"
    empty.mkdir()
    wants = cli_errors(["info", missing, "--json"], ["info", path, "--json", "--crop", "4,0,3,3"],
                       ["info", path, "--json", "--crop", "0,0,0,3"], ["info", path, "--json", "--layout", "ubo2099"],
                       ["info", empty, "--json"])
    with pytest.raises(FileNotFoundError) as e:
        nbtf.load_stack(missing)
    assert str(e.value) == wants[0]
    with pytest.raises(ValueError) as e:
        nbtf.load_stack(path, crop=(4, 0, 3, 3))
    assert str(e.value) == wants[1]
    with pytest.raises(ValueError) as e:
        nbtf.load_stack(path, crop=(0, 0, 0, 3))
    assert str(e.value) == wants[2]
    with pytest.raises(ValueError) as e:
        nbtf.load_stack(path, layout="ubo2099")
    assert str(e.value) == wants[3]
    with pytest.raises(ValueError) as e:
        nbtf.load_stack(empty)
    assert str(e.value) == wants[4]
    # A folder is not a UBO2014 file: --layout ubo2014 is refused, as on the command line.
    want = cli_error("info", path, "--json", "--layout", "ubo2014")
    assert "--layout ubo2014 applies to UBO2014 .btf files only" in want
    with pytest.raises(ValueError) as e:
        nbtf.load_stack(path, layout="ubo2014")
    assert str(e.value) == want
    with pytest.raises(ValueError, match=r"crop: expected \(x, y, width, height\)"):
        nbtf.load_stack(path, crop=(1, 2))
    with pytest.raises(ValueError, match="progress: expected a callable"):
        nbtf.load_stack(path, progress=3)


def test_too_large_is_refused_before_loading(png_stack):
    path, _ = png_stack
    with pytest.raises(ValueError, match=r"5 x 4 texels x 6 images \(8-bit\) need about .* memory_limit 100 allows "
                                         r"100 B\. Load a part of it \(crop=\(x, y, w, h\)\) or raise memory_limit"):
        nbtf.load_stack(path, memory_limit=100)
    with pytest.raises(ValueError, match=r"memory_limit: "):
        nbtf.load_stack(path, memory_limit="lots")


def test_progress_callback(png_stack):
    path, _ = png_stack
    seen = []
    nbtf.load_stack(path, progress=seen.append)
    assert seen and seen[-1]["final"] and seen[-1]["done"] == seen[-1]["total"]
    assert set(seen[-1]) == {"label", "done", "total", "seconds", "status", "final"}

    def fail(update):
        raise RuntimeError("stop here")

    with pytest.raises(RuntimeError, match="stop here"):
        nbtf.load_stack(path, progress=fail)


@pytest.fixture(scope="module")
def ubo2014_btf(tmp_path_factory, bin_dir):
    out = tmp_path_factory.mktemp("ubo2014") / "fabric.btf"
    import subprocess

    subprocess.run([os.path.join(bin_dir, "nbtf-synth"), "--size", "8", "--layout", "ubo2014", "--components", "4",
                    "-q", "-o", str(out)], check=True, capture_output=True)
    return str(out)


def test_ubo2014_btf(ubo2014_btf):
    info = cli_json("info", ubo2014_btf, "--json")
    s = nbtf.load_stack(ubo2014_btf, crop=(0, 0, 4, 2))
    assert s.layout == "ubo2014" and s.images.shape == (info["images"], 2, 4, 3)
    assert s.samples == "half float (linear)" and not s.computed
    raw = nbtf.load_stack(ubo2014_btf, crop=(0, 0, 4, 2), linear=False)
    assert raw.images.dtype == np.float16
    np.testing.assert_array_equal(raw.images.astype(np.float32), s.images)
    # Too large to expand under the limit (half of it, as for compress): the file stays
    # factorized, its float32 copy is refused.
    with pytest.raises(ValueError, match=r"fabric.btf: 8 x 8 texels x 22801 images \(computed from UBO2014 factors\) "
                                         r"need about .* memory_limit 4M allows 4 MiB"):
        nbtf.load_stack(ubo2014_btf, memory_limit="4M")
    with pytest.raises(ValueError, match=r"is kept as its factors, its values computed when read: it has no stored "
                                         r"samples \(linear=True gives them\)"):
        nbtf.load_stack(ubo2014_btf, memory_limit="4M", linear=False)
