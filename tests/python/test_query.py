# Material.query, .info and .sizes against `nbtf query` and `nbtf info --json`, on every
# committed .nbtf file (each format version, each method).
import os

import numpy as np
import pytest

import nbtf
from conftest import as_float32, cli, cli_json, committed_nbtf_files

FILES = committed_nbtf_files()


def ids(files):
    return [os.path.relpath(f, os.path.dirname(os.path.dirname(f))) for f in files]


def queries(m, count=40, seed=7):
    """Texels and (theta, phi) pairs: measured and unmeasured angles, the hemisphere's edges."""
    rng = np.random.default_rng(seed)
    xy = np.stack([rng.integers(0, m.width, count), rng.integers(0, m.height, count)], axis=1)
    light = np.stack([rng.uniform(0, 90, count).round(2), rng.uniform(-30, 400, count).round(2)], axis=1)
    view = np.stack([rng.uniform(0, 90, count).round(2), rng.uniform(0, 360, count).round(2)], axis=1)
    light[:3] = [[0, 0], [90, 0], [75, 345]]
    view[:3] = [[0, 0], [15, 60], [90, 180]]
    if len(m.lights):  # measured directions, as the file stores them
        light[3], view[3] = m.lights[-1], m.views[len(m.views) // 2]
    return xy, light, view


def cli_batch(path, xy, light, view, normalized, tmp_path):
    csv = tmp_path / "queries.csv"
    lines = [f"{x},{y},{lt!r},{lp!r},{vt!r},{vp!r}" for (x, y), (lt, lp), (vt, vp) in
             zip(xy.tolist(), light.tolist(), view.tolist())]
    csv.write_text("\n".join(lines) + "\n")
    args = ["query", path, "--batch", csv] + (["--normalized"] if normalized else [])
    out = cli(*args).stdout.strip().splitlines()[1:]
    return np.array([[as_float32(v) for v in line.split(",")[6:]] for line in out], dtype=np.float32)


# Every file in linear RGB; the normalized output (the same path without the alpha) on three.
CASES = [(f, False) for f in FILES] + [(f, True) for f in FILES if os.path.basename(f) in
                                       ("legacy_v1_0.nbtf", "compact_v1_7.nbtf", "pca.nbtf")]


@pytest.mark.parametrize("path,normalized", CASES, ids=[f"{i}-{'normalized' if n else 'linear'}" for i, (_, n) in
                                                         zip(ids([c[0] for c in CASES]), CASES)])
def test_query_equals_cli_batch_bit_for_bit(path, normalized, tmp_path):
    with nbtf.open(path) as m:
        xy, light, view = queries(m)
        got = m.query(texel=xy, light=light, view=view, normalized=normalized)
    want = cli_batch(path, xy, light, view, normalized, tmp_path)
    assert got.dtype == np.float32 and got.shape == (len(xy), 3)
    # %.9g reads back as the same float32: equality is bit for bit.
    np.testing.assert_array_equal(got, want)


# Single queries take another road through the command line (no batch): three files suffice.
SINGLE = [f for f in FILES if os.path.basename(f) in ("legacy_v1_0.nbtf", "compact_v1_7.nbtf", "pca.nbtf")]


@pytest.mark.parametrize("path", SINGLE, ids=ids(SINGLE))
def test_single_queries_equal_cli(path):
    with nbtf.open(path) as m:
        for uv in [(0.3, 0.7), (-0.25, 1.6)]:
            want = cli("query", path, "--uv", f"{uv[0]},{uv[1]}", "--light", "30,60", "--view", "45,180").stdout.split()
            got = m.query(uv=uv, light=(30, 60), view=(45, 180))
            np.testing.assert_array_equal(got, np.array([as_float32(v) for v in want], dtype=np.float32))
        want = cli("query", path, "--texel", "1,1", "--light", "12.5,300", "--view", "0,0", "--normalized").stdout.split()
        got = m.query(texel=(1, 1), light=(12.5, 300), view=(0, 0), normalized=True)
        assert got.shape == (3,)
        np.testing.assert_array_equal(got, np.array([as_float32(v) for v in want], dtype=np.float32))


@pytest.mark.parametrize("path", FILES, ids=ids(FILES))
def test_info_equals_cli_info_json(path):
    want = cli_json("info", path, "--json")
    with nbtf.open(path) as m:
        assert m.info == want
        sizes = m.sizes
        for key in ("total", "raw_float32", "file", "ratio"):
            assert sizes[key] == want["bytes"][key] if key != "ratio" else sizes[key] == want["ratio"]
        if want["method"] != "pca":
            assert (sizes["decoder"], sizes["latents"], sizes["ids"]) == (
                want["bytes"]["decoder"], want["bytes"]["latents"], want["bytes"]["ids"])
        assert sizes["file"] == os.path.getsize(path)
        assert (m.width, m.height) == (want["width"], want["height"])
        assert m.lights.shape == (want["lights"], 2) and m.views.shape == (want["views"], 2)


def test_unit_vectors_agree_with_angles():
    path = os.path.join(os.path.dirname(FILES[0]), "compact_v1_7.nbtf")
    with nbtf.open(path) as m:
        xy, light, view = queries(m, count=20)
        by_angles = m.query(texel=xy, light=light, view=view)

        def vec(d):
            t, p = np.radians(d[:, 0]), np.radians(d[:, 1])
            return np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=1)

        by_vectors = m.query(texel=xy, light=vec(light), view=3 * vec(view))  # normalized by the decoder
        np.testing.assert_allclose(by_vectors, by_angles, rtol=1e-4, atol=1e-5)
        # uv at the texel centres selects the same texels
        uv = (xy + 0.5) / [m.width, m.height]
        np.testing.assert_array_equal(m.query(uv=uv, light=light, view=view), by_angles)
        np.testing.assert_array_equal(m.query(uv=uv, light=vec(light), view=vec(view)),
                                      m.query(texel=xy, light=vec(light), view=vec(view)))


def test_broadcasting_like_numpy():
    path = os.path.join(os.path.dirname(FILES[0]), "compact_v1_7.nbtf")
    with nbtf.open(path) as m:
        texels = np.array([[x, y] for y in range(4) for x in range(5)]).reshape(4, 5, 2)
        lights = np.array([[10, 20], [30, 40], [50, 60]]).reshape(3, 1, 1, 2)
        got = m.query(texel=texels, light=lights, view=(45, 180))
        assert got.shape == (3, 4, 5, 3)
        for i in range(3):
            for y in range(4):
                for x in range(5):
                    np.testing.assert_array_equal(got[i, y, x], m.query(texel=(x, y), light=lights[i, 0, 0],
                                                                        view=(45, 180)))
        assert m.query(texel=np.zeros((0, 2), int), light=(1, 2), view=(3, 4)).shape == (0, 3)
        # integers of any width and lists work alike
        a = m.query(texel=np.array([2, 3], dtype=np.uint8), light=[30, 60], view=(45, 180))
        b = m.query(texel=(2, 3), light=np.array([30.0, 60.0], dtype=np.float32), view=(45, 180))
        np.testing.assert_array_equal(a, b)
