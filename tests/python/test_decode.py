# Material.decode_image against `nbtf decode` (its half-float EXR output in linear RGB, read
# back by the library's EXR reader).
import glob
import os

import numpy as np
import pytest

import nbtf
from nbtf import _nbtf
from conftest import cli, committed_nbtf_files

FILES = committed_nbtf_files()


def cli_decode(path, light, view, out, size=None):
    # The UBO2003 layout: its EXRs hold linear RGB (UTIA's hold CIE XYZ, a conversion each way).
    args = ["decode", path, "-o", out, "--layout", "ubo2003", "--format", "exr", "-q", "--light", f"{light[0]!r},{light[1]!r}",
            "--view", f"{view[0]!r},{view[1]!r}"]
    if size:
        args += ["--size", f"{size[0]}x{size[1]}"]
    cli(*args)
    (exr,) = glob.glob(os.path.join(out, "**", "*.exr"), recursive=True)
    return _nbtf.read_exr(exr)


def as_written(img):
    """What `nbtf decode` writes of an image: negative values clamped to 0, half floats."""
    return np.maximum(img, 0).astype(np.float16).astype(np.float32)


@pytest.mark.parametrize("path", FILES, ids=[os.path.basename(f) for f in FILES])
def test_decode_image_equals_cli_decode(path, tmp_path):
    with nbtf.open(path) as m:
        pairs = [((37.5, 200.0), (10.0, 45.0))]  # unmeasured
        if os.path.basename(path) in ("compact_v1_7.nbtf", "legacy_v1_0.nbtf", "pca.nbtf"):
            pairs.append((tuple(m.lights[len(m.lights) // 3]), tuple(m.views[-1])))  # measured
        for i, (light, view) in enumerate(pairs):
            img = m.decode_image(light, view)
            assert img.shape == (m.height, m.width, 3) and img.dtype == np.float32
            want = cli_decode(path, light, view, str(tmp_path / f"d{i}"))
            np.testing.assert_array_equal(as_written(img), want)
            # the texels are the queries' values
            ys, xs = np.mgrid[0:m.height, 0:m.width]
            q = m.query(texel=np.stack([xs, ys], axis=-1), light=light, view=view)
            np.testing.assert_allclose(img, q, rtol=1e-5, atol=1e-6)


def test_decode_image_tiles_to_a_size(tmp_path):
    path = FILES[-1]
    with nbtf.open(path) as m:
        img = m.decode_image((30, 60), (45, 180), size=(m.width + 5, 2 * m.height))
        assert img.shape == (2 * m.height, m.width + 5, 3)
        np.testing.assert_array_equal(img[m.height:, :m.width], img[:m.height, :m.width])
        np.testing.assert_array_equal(img[:, m.width:], img[:, :5])
        want = cli_decode(path, (30.0, 60.0), (45.0, 180.0), str(tmp_path / "tiled"), size=(m.width + 5, 2 * m.height))
        np.testing.assert_array_equal(as_written(img), want)
        normalized = m.decode_image((30, 60), (45, 180), normalized=True)
        np.testing.assert_allclose(normalized * m.alpha, m.decode_image((30, 60), (45, 180)), rtol=1e-6)
        # a direction as a unit vector: the same image as its angles (to float precision)
        t, p = np.radians(30), np.radians(60)
        by_vector = m.decode_image((np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)), (45, 180))
        np.testing.assert_allclose(by_vector, m.decode_image((30, 60), (45, 180)), rtol=1e-4, atol=1e-6)
