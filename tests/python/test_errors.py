# Every error path of the module raises (never crashes the interpreter), with the command
# line's message: OSError for files, ValueError for arguments and data.
import errno
import os
import shutil

import numpy as np
import pytest

import nbtf
from conftest import ROOT, cli_error, cli_errors

V17 = os.path.join(ROOT, "tests", "data", "compact_v1_7.nbtf")


@pytest.fixture
def m():
    with nbtf.open(V17) as material:
        yield material


def test_missing_file_is_file_not_found_with_the_cli_message(tmp_path):
    path = str(tmp_path / "missing.nbtf")
    want = cli_error("query", path, "--texel", "0,0", "--light", "0,0", "--view", "0,0")
    with pytest.raises(FileNotFoundError) as e:
        nbtf.open(path)
    assert str(e.value) == want
    assert e.value.errno == errno.ENOENT


def test_folder_is_an_os_error(tmp_path):
    with pytest.raises(IsADirectoryError, match="is a folder, expected a file"):
        nbtf.open(tmp_path)
    assert "is a folder, expected a file" in cli_error("query", tmp_path, "--texel", "0,0", "--light", "0,0",
                                                       "--view", "0,0")


def test_damaged_file_is_a_value_error_with_the_cli_message(tmp_path):
    bad = tmp_path / "bad.nbtf"
    bad.write_bytes(b"not an nbtf file at all")
    want = cli_error("info", bad, "--json")
    with pytest.raises(ValueError) as e:
        nbtf.open(bad)
    assert str(e.value) == want
    truncated = tmp_path / "truncated.nbtf"
    truncated.write_bytes(open(V17, "rb").read()[:200])
    want = cli_error("info", truncated, "--json")
    with pytest.raises(ValueError) as e:
        nbtf.open(truncated)
    assert str(e.value) == want


def test_bad_isa(tmp_path):
    want = cli_error("query", V17, "--isa", "sse9", "--texel", "0,0", "--light", "0,0", "--view", "0,0")
    with pytest.raises(ValueError) as e:
        nbtf.open(V17, isa="sse9")
    assert str(e.value) == want


def test_values_out_of_range_have_the_cli_messages(m):
    cases = [
        ({"texel": (16, 0), "light": (30, 60), "view": (45, 180)}, ["--texel", "16,0", "--light", "30,60", "--view", "45,180"]),
        ({"texel": (0, -1), "light": (30, 60), "view": (45, 180)}, ["--texel", "0,-1", "--light", "30,60", "--view", "45,180"]),
        ({"texel": (0, 0), "light": (95, 60), "view": (45, 180)}, ["--texel", "0,0", "--light", "95,60", "--view", "45,180"]),
        ({"texel": (0, 0), "light": (30, 60), "view": (-1, 180)}, ["--texel", "0,0", "--light", "30,60", "--view", "-1,180"]),
    ]
    wants = cli_errors(*[["query", V17, *args] for _, args in cases])
    for (kwargs, _), want in zip(cases, wants):
        # The command line names its options (--light), the module its keywords (light).
        want = want.replace("--light", "light").replace("--view", "view")
        with pytest.raises(ValueError) as e:
            m.query(**kwargs)
        assert str(e.value) == want


def test_batches_name_the_bad_query(m):
    with pytest.raises(ValueError, match=r"^query 2: texel \(16, 0\) is outside the 16 x 16 material"):
        m.query(texel=[(0, 0), (1, 1), (16, 0)], light=(30, 60), view=(45, 180))
    with pytest.raises(ValueError, match=r"^query 1: light direction is not finite"):
        m.query(texel=(0, 0), light=[(30, 60), (np.nan, 1)], view=(45, 180))
    with pytest.raises(ValueError, match=r"^query 0: view direction vector is not finite"):
        m.query(uv=[(0, 0), (0, 1)], light=(0, 0, 1), view=(np.inf, 0, 1))
    with pytest.raises(ValueError, match=r"^texture coordinate \(u, v\) is not finite"):
        m.query(uv=(np.nan, 0), light=(30, 60), view=(45, 180))
    with pytest.raises(ValueError, match=r"light direction vector has zero length"):
        m.query(uv=(0, 0), light=(0, 0, 0), view=(0, 0, 1))
    with pytest.raises(ValueError, match=r"points below the horizon \(z < 0; z is the surface normal\)"):
        m.query(uv=(0, 0), light=(0, 0, 1), view=(0, 1, -1))
    # A texel far outside the int32 range is still outside the material, not wrapped into it.
    with pytest.raises(ValueError, match=r"^texel \(4294967297, 0\) is outside the 16 x 16 material"):
        m.query(texel=(2**32 + 1, 0), light=(30, 60), view=(45, 180))
    with pytest.raises(ValueError, match=r"^query 1: texel \(1099511627776, 0\) is outside the 16 x 16 material"):
        m.query(texel=[(0, 0), (2**40, 0)], light=(30, 60), view=(45, 180))


def test_wrong_dtypes_and_shapes(m):
    ok = {"light": (30, 60), "view": (45, 180)}
    with pytest.raises(ValueError, match="texel: expected integer"):
        m.query(texel=(1.0, 2.0), **ok)
    with pytest.raises(ValueError, match="texel: expected numbers, got dtype <U1"):
        m.query(texel=("a", "b"), **ok)
    with pytest.raises(ValueError, match=r"texel: expected \(\.\.\., 2\) arrays of \(x, y\), got shape \(3,\)"):
        m.query(texel=(1, 2, 3), **ok)
    with pytest.raises(ValueError, match="give exactly one of texel= "):
        m.query(light=(30, 60), view=(45, 180))
    with pytest.raises(ValueError, match="give exactly one of texel= "):
        m.query(texel=(0, 0), uv=(0, 0), **ok)
    with pytest.raises(ValueError, match=r"light: expected \(theta, phi\) in degrees \(last axis 2\) or unit vectors"):
        m.query(texel=(0, 0), light=(1, 2, 3, 4), view=(45, 180))
    with pytest.raises(ValueError, match="light: expected numbers, got dtype object"):
        m.query(texel=(0, 0), light=np.array([None, 1], dtype=object), view=(45, 180))
    with pytest.raises(ValueError, match="light and view: give both as"):
        m.query(texel=(0, 0), light=(30, 60), view=(0, 0, 1))
    with pytest.raises(ValueError, match="do not broadcast together"):
        m.query(texel=np.zeros((3, 2), int), light=np.zeros((2, 2)), view=(45, 180))
    with pytest.raises(ValueError, match="not an array of numbers"):
        m.query(texel=[(0, 0), (1,)], **ok)
    with pytest.raises(ValueError, match="decode_image takes one direction"):
        m.decode_image(light=[(30, 60), (1, 2)], view=(0, 0))
    with pytest.raises(ValueError, match=r"size: expected \(width, height\)"):
        m.decode_image((30, 60), (0, 0), size=(4,))
    with pytest.raises(ValueError, match=r"each at least 1"):
        m.decode_image((30, 60), (0, 0), size=(0, 4))
    with pytest.raises(ValueError, match="light direction theta = 91 degrees is outside the upper hemisphere"):
        m.decode_image((91, 0), (0, 0))
    with pytest.raises(ValueError, match="view direction is not finite"):
        m.decode_image((30, 0), (0, np.nan))
    with pytest.raises(TypeError, match="path: expected a path"):
        nbtf.open(3)


def test_closed_material_raises(m):
    m.close()
    m.close()  # twice is fine, as for files
    assert m.closed
    for use in (lambda: m.query(texel=(0, 0), light=(0, 0), view=(0, 0)), lambda: m.decode_image((0, 0), (0, 0)),
                lambda: m.info, lambda: m.sizes, lambda: m.width, lambda: m.lights):
        with pytest.raises(ValueError, match="compact_v1_7.nbtf: the material is closed"):
            use()
    assert "closed" in repr(m)


def test_threads():
    with pytest.raises(ValueError, match="--threads must be >= 0, got -1"):
        nbtf.set_threads(-1)
    with pytest.raises(ValueError, match="threads: expected an integer"):
        nbtf.set_threads(1.5)
    nbtf.set_threads(1)
    assert nbtf.threads() == 1
    nbtf.set_threads(0)
    assert nbtf.threads() == os.cpu_count()
