# The package itself: `import nbtf` and queries never load libtorch; the GIL is released while
# decoding; the example script runs.
import os
import subprocess
import sys
import threading

import numpy as np

import nbtf
from conftest import ROOT

V17 = os.path.join(ROOT, "tests", "data", "compact_v1_7.nbtf")


def run_python(code, *args):
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, env=os.environ.copy())


def test_import_and_query_do_not_load_torch():
    code = """
import sys, nbtf
with nbtf.open(sys.argv[1]) as m:
    m.query(texel=(1, 1), light=(30, 60), view=(0, 0))
    m.decode_image((30, 60), (0, 0))
maps = open('/proc/self/maps').read()
print('torch' if ('libtorch' in maps or 'libc10' in maps) else 'no torch', '_nbtf_train' in sys.modules)
nbtf._train()
maps = open('/proc/self/maps').read()
print('torch' if 'libtorch' in maps else 'no torch')
"""
    r = run_python(code, V17)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split("\n")[:2] == ["no torch False", "torch"], r.stdout


def test_decoding_releases_the_gil():
    # Two Python threads decode at once and give the single-threaded results.
    with nbtf.open(V17) as m:
        xy = np.stack(np.meshgrid(np.arange(16), np.arange(16)), axis=-1).reshape(-1, 2)
        xy = np.tile(xy, (200, 1))
        want = m.query(texel=xy, light=(30, 60), view=(45, 180))
        results = [None, None]

        def work(i):
            try:
                results[i] = m.query(texel=xy, light=(30, 60), view=(45, 180))
            except ValueError as e:  # started after close()
                results[i] = str(e)

        threads = [threading.Thread(target=work, args=(i,)) for i in range(2)]
        for t in threads:
            t.start()
        m.close()  # the decodes in flight keep their decoder
        for t in threads:
            t.join()
    for r in results:
        if isinstance(r, str):
            assert r.endswith("compact_v1_7.nbtf: the material is closed")
        else:
            np.testing.assert_array_equal(r, want)


def test_render_sphere_example(tmp_path):
    out = tmp_path / "sphere.ppm"
    script = os.path.join(ROOT, "examples", "python", "render_sphere.py")
    r = subprocess.run([sys.executable, script, V17, "-o", str(out), "--size", "48"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    data = out.read_bytes()
    assert data.startswith(b"P6\n48 48\n255\n") and len(data) == len(b"P6\n48 48\n255\n") + 48 * 48 * 3
    pixels = np.frombuffer(data[len(b"P6\n48 48\n255\n"):], dtype=np.uint8).reshape(48, 48, 3)
    assert pixels[24, 24].sum() > 0 and pixels[0, 0].sum() == 0  # the sphere is lit, the corner is background


def test_version_and_repr():
    assert nbtf.__version__
    with nbtf.open(V17) as m:
        assert "compact_v1_7.nbtf" in repr(m) and "format 1.7" in repr(m)
