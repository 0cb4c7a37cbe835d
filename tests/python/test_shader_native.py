# scripts/shader_native.py: the exported shader on the machine's own OpenGL ES driver (Mesa's
# llvmpipe here, through EGL's surfaceless platform) against the C++ decoder. Skipped where no
# EGL display can be opened.
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from conftest import ROOT

SCRIPT = os.path.join(ROOT, "scripts", "shader_native.py")
FILE = os.path.join(ROOT, "tests", "data", "compact_v1_8.nbtf")


def script(*args):
    env = dict(os.environ)
    env.setdefault("EGL_PLATFORM", "surfaceless")  # no display here: Mesa's surfaceless platform
    return subprocess.run([sys.executable, SCRIPT, *map(str, args)], capture_output=True, text=True, env=env)


def run_or_skip(out, *args):
    r = script("run", out, "--size", 16, "--frames", 1, *args)
    if r.returncode == 2 and ("EGL" in r.stderr or "could be loaded" in r.stderr):
        pytest.skip(f"no OpenGL ES 3 through EGL here: {r.stderr.strip()}")
    return r


@pytest.mark.parametrize("stage", ["fragment", "compute"])
def test_the_native_shader_decodes_as_the_cpp_decoder(tmp_path, stage):
    r = script("prepare", FILE, tmp_path)
    assert r.returncode == 0, r.stderr
    r = run_or_skip(tmp_path, "--stage", stage, "--json", tmp_path / "summary.json")
    assert r.returncode == 0, r.stdout + r.stderr
    summary = json.load(open(tmp_path / "summary.json"))
    assert summary["pass"] and summary["stage"] == stage
    assert summary["pairs"] == 5 and summary["texels"] == [16, 16]
    assert summary["max_abs_difference"] < 1e-5 * summary["reference_max"]
    assert summary["frame_pixels"] == 256 and summary["frame_ms_median"] > 0


def test_a_wrong_reference_fails_the_check(tmp_path):
    assert script("prepare", FILE, tmp_path).returncode == 0
    reference = dict(np.load(tmp_path / "reference.npz"))
    reference["images"][2, 7, 3, 1] += 0.01 * np.abs(reference["images"]).max()  # one value off by 1%
    np.savez(tmp_path / "reference.npz", **reference)
    r = run_or_skip(tmp_path, "--json", tmp_path / "summary.json")
    assert r.returncode == 1, r.stdout + r.stderr
    summary = json.load(open(tmp_path / "summary.json"))
    assert not summary["pass"]
    assert summary["max_abs_difference"] == pytest.approx(0.01 * summary["reference_max"], rel=1e-3)


def test_a_shader_that_does_not_compile_is_reported_with_the_drivers_log(tmp_path):
    assert script("prepare", FILE, tmp_path).returncode == 0
    with open(tmp_path / "export" / "nbtf_decoder.glsl", "a") as f:
        f.write("\nthis is not GLSL\n")
    r = run_or_skip(tmp_path)
    assert r.returncode == 2, r.stdout + r.stderr
    assert "the decoder's fragment shader does not compile" in r.stderr
    assert "error" in r.stderr.lower()
