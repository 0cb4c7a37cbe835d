# Fixtures of the Python module's tests (run by ctest as python.pytest, or by hand:
#   PYTHONPATH=build/python NBTF_BIN_DIR=build/bin python3 -m pytest tests/python
# ). The command line is the reference: every test compares the module with `nbtf ...`.
import glob
import json
import os
import subprocess

import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BIN = os.environ.get("NBTF_BIN_DIR", os.path.join(ROOT, "build", "bin"))


def committed_nbtf_files():
    """Every committed .nbtf file: one per format version (tests/data) and one per method
    (fuzz/corpus: clustered, per-texel, PCA)."""
    files = sorted(glob.glob(os.path.join(ROOT, "tests", "data", "*.nbtf")))
    files += sorted(glob.glob(os.path.join(ROOT, "fuzz", "corpus", "*.nbtf")))
    return files


def cli(*args, check=True, input=None):
    """Runs `nbtf ARGS...`; returns the CompletedProcess (text)."""
    r = subprocess.run([os.path.join(BIN, "nbtf"), *map(str, args)], capture_output=True, text=True, input=input)
    if check and r.returncode != 0:
        raise AssertionError(f"nbtf {' '.join(map(str, args))} failed ({r.returncode}):\n{r.stdout}\n{r.stderr}")
    return r


def cli_json(*args):
    return json.loads(cli(*args).stdout)


def cli_error(*args):
    """The message of a failing `nbtf CMD ...`, without its "nbtf CMD: error: " prefix."""
    r = cli(*args, check=False)
    assert r.returncode != 0, r.stdout
    line = r.stderr.strip().splitlines()[-1]
    return line.split(": error: ", 1)[1]


def cli_errors(*commands):
    """cli_error of several commands (argument lists), run side by side: each is mostly the
    program's start."""
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(max_workers=4) as pool:
        return list(pool.map(lambda args: cli_error(*args), commands))


@pytest.fixture(scope="session")
def bin_dir():
    return BIN


@pytest.fixture(scope="session")
def synth_stack(tmp_path_factory):
    """nbtf-synth's fabric at 8 x 8 texels, UTIA layout, PNG (81 x 81 directions)."""
    out = tmp_path_factory.mktemp("synth") / "fabric8"
    subprocess.run([os.path.join(BIN, "nbtf-synth"), "--size", "8", "--layout", "utia", "--no-ground-truth", "-q",
                    "-o", str(out)], check=True, capture_output=True)
    return str(out)


@pytest.fixture(scope="session")
def synth_nbtf(synth_stack, tmp_path_factory):
    """A quick .nbtf of synth_stack, made by the command line."""
    out = tmp_path_factory.mktemp("synth_nbtf") / "fabric8.nbtf"
    cli("compress", synth_stack, "-o", out, "--clusters", 4, "--epochs", 1, "--config", "compact", "--seed", 1,
        "--threads", 1, "-q")
    return str(out)


def as_float32(text):
    return np.float32(float(text))
