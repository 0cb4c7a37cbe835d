# nbtf.compress and nbtf.evaluate against `nbtf compress` and `nbtf eval` on a tiny material
# (nbtf-synth at 8 x 8 texels, one epoch of the compact config: seconds).
import json
import os

import numpy as np
import pytest

import nbtf
from conftest import cli, cli_error, cli_errors, cli_json

QUICK = dict(clusters=4, epochs=1, config="compact", seed=1, threads=1, quiet=True)
QUICK_CLI = ["--clusters", "4", "--epochs", "1", "--config", "compact", "--seed", "1", "--threads", "1", "-q"]


def without_times(stats):
    """A --stats-json summary without what differs between two identical runs (times, memory)."""
    s = dict(stats)
    for key in ("seconds", "samples_per_second", "decoder_gflops", "memory", "peak_memory", "output"):
        s.pop(key, None)
    return s


def test_compress_gives_the_cli_bytes(synth_stack, synth_nbtf, tmp_path):
    out = tmp_path / "py.nbtf"
    stats_file = tmp_path / "py.stats.json"
    stats = nbtf.compress(synth_stack, out, stats_json=stats_file, **QUICK)
    assert open(out, "rb").read() == open(synth_nbtf, "rb").read()
    assert stats == json.loads(stats_file.read_text())
    cli_stats = tmp_path / "cli.stats.json"
    cli("compress", synth_stack, "-o", tmp_path / "cli.nbtf", *QUICK_CLI, "--stats-json", cli_stats)
    assert without_times(stats) == without_times(json.loads(cli_stats.read_text()))
    assert stats["clusters"] == 4 and stats["bytes"]["file"] == os.path.getsize(out)
    with nbtf.open(out) as m:
        assert m.info["clusters"] == 4


def test_option_names_are_the_cli_ones(synth_stack, tmp_path):
    # crop=(x, y, w, h), holdout, method="pca" + components: the same file as the command line's
    out = tmp_path / "pca.nbtf"
    nbtf.compress(synth_stack, out, method="pca", components=3, crop=(1, 2, 5, 4), holdout=0.1, seed=2, quiet=True)
    cli("compress", synth_stack, "-o", tmp_path / "pca_cli.nbtf", "--method", "pca", "--components", "3",
        "--crop", "1,2,5,4", "--holdout", "0.1", "--seed", "2", "-q")
    assert open(out, "rb").read() == open(tmp_path / "pca_cli.nbtf", "rb").read()
    with nbtf.open(out) as m:
        assert (m.width, m.height) == (5, 4) and m.info["crop"] == [1, 2, 5, 4]


def test_size_budget_chooses_the_point(synth_stack, tmp_path):
    # size_budget= without adaptive: the named config and k that fit, the file within the budget;
    # the same file as the command line's.
    out = tmp_path / "b.nbtf"
    stats = nbtf.compress(synth_stack, out, size_budget="60K", epochs=1, seed=1, threads=1, quiet=True)
    assert os.path.getsize(out) <= 60 * 1024
    budget = stats["size_budget"]
    assert budget["bytes"] == 60 * 1024 and os.path.getsize(out) <= budget["estimate_bytes"] <= 60 * 1024
    assert budget["config"] in ("compact", "default", "balanced", "high_fidelity")
    cli("compress", synth_stack, "-o", tmp_path / "b_cli.nbtf", "--size-budget", "60K", "--epochs", "1", "--seed", "1",
        "--threads", "1", "-q")
    assert open(out, "rb").read() == open(tmp_path / "b_cli.nbtf", "rb").read()
    with nbtf.open(out) as m:
        assert m.info["clusters"] == stats["clusters"]


def test_progress_callback(synth_stack, tmp_path):
    seen = []
    nbtf.compress(synth_stack, tmp_path / "p.nbtf", progress=seen.append, **{**QUICK, "quiet": False})
    labels = {u["label"] for u in seen}
    assert seen and any(u["final"] for u in seen), seen
    assert len(labels) >= 2, labels  # loading, clustering, training...
    # quiet silences the text bars, not the callback.
    quiet = []
    nbtf.compress(synth_stack, tmp_path / "q.nbtf", progress=quiet.append, **QUICK)
    assert quiet and {u["label"] for u in quiet} == labels, quiet

    def fail(update):
        raise KeyError("from the callback")

    with pytest.raises(KeyError, match="from the callback"):
        nbtf.compress(synth_stack, tmp_path / "f.nbtf", progress=fail, **{**QUICK, "quiet": False})


def test_compress_errors_have_the_cli_messages(synth_stack, tmp_path):
    out = str(tmp_path / "x.nbtf")
    cases = [
        (dict(clusters=-3), ["--clusters", "-3"]),
        (dict(clusters="abc"), ["--clusters", "abc"]),
        (dict(holdout=1.5), ["--holdout", "1.5"]),
        (dict(method="pca"), ["--method", "pca"]),
        (dict(config="compactt"), ["--config", "compactt"]),
        (dict(crop=(0, 0, 100, 100)), ["--crop", "0,0,100,100"]),
        (dict(target_rmse=0.1), ["--target-rmse", "0.1"]),
        (dict(memory_limit="12X"), ["--memory-limit", "12X"]),
        (dict(size_budget="1M", clusters=5), ["--size-budget", "1M", "--clusters", "5"]),
    ]
    wants = cli_errors(*[["compress", synth_stack, "-o", out, *args, "-q"] for _, args in cases])
    keywords = nbtf._compress_keywords()
    for (kwargs, _), want in zip(cases, wants):
        with pytest.raises(ValueError) as e:
            nbtf.compress(synth_stack, out, quiet=True, **kwargs)
        # The command line's message, its options named as the keywords given.
        assert str(e.value) == nbtf._python_names(want, keywords), kwargs
        keyword = next(iter(kwargs))
        assert "--" + keyword.replace("_", "-") not in str(e.value), str(e.value)
        if want.find("--" + keyword.replace("_", "-")) >= 0:
            assert keyword + "=" in str(e.value), str(e.value)
    # An unknown keyword is a TypeError, as for any Python function (and for open and evaluate).
    with pytest.raises(TypeError, match=r"compress\(\) got an unexpected keyword argument 'cropp'; did you mean 'crop'\?"):
        nbtf.compress(synth_stack, out, cropp=(0, 0, 4, 4))
    with pytest.raises(TypeError, match="unexpected keyword argument 'no_such_option'"):
        nbtf.compress(synth_stack, out, no_such_option=1)
    with pytest.raises(TypeError, match="unexpected keyword argument 'output'"):
        nbtf.compress(synth_stack, out, output="y.nbtf")
    with pytest.raises(TypeError, match="unexpected keyword argument 'cropp'"):
        nbtf.evaluate(out, synth_stack, cropp=(0, 0, 4, 4))
    missing = str(tmp_path / "missing")
    with pytest.raises(FileNotFoundError) as e:
        nbtf.compress(missing, out, quiet=True)
    assert str(e.value) == cli_error("compress", missing, "-o", out, "-q")
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(NotADirectoryError) as e:
        nbtf.compress(synth_stack, blocker / "x.nbtf", quiet=True)
    assert str(e.value) == cli_error("compress", synth_stack, "-o", blocker / "x.nbtf", "-q")
    with pytest.raises(ValueError) as e:
        nbtf.compress(synth_stack, synth_stack, quiet=True)
    assert str(e.value) == cli_error("compress", synth_stack, "-o", synth_stack, "-q")
    assert not os.path.exists(out)


def test_evaluate_equals_cli_eval(synth_stack, synth_nbtf, tmp_path):
    report = nbtf.evaluate(synth_nbtf, synth_stack, output=tmp_path / "py", blur_images=1, quiet=True)
    cli("eval", synth_nbtf, "--reference", synth_stack, "-o", tmp_path / "cli", "--blur-images", "1", "-q")
    want = json.loads((tmp_path / "cli" / "report.json").read_text())
    assert report == json.loads((tmp_path / "py" / "report.json").read_text())

    def strip(r):  # times differ between runs
        r = json.loads(json.dumps(r))
        r.pop("seconds", None)
        for section in r.values():
            if isinstance(section, dict):
                section.pop("seconds", None)
        return r

    assert strip(report) == strip(want)
    assert report["metrics"]["all"]["rmse"] > 0 if "metrics" in report else True
    # without output= nothing is written
    again = nbtf.evaluate(synth_nbtf, synth_stack, blur_images=1, quiet=True)
    assert strip(again) == strip(report)


def test_evaluate_errors(synth_stack, synth_nbtf, tmp_path):
    missing = str(tmp_path / "missing.nbtf")
    report = str(tmp_path / "r")
    wants = cli_errors(
        ["eval", missing, "--reference", synth_stack, "-o", report, "-q"],
        ["eval", synth_nbtf, "--reference", synth_stack, "-o", report, "--crop", "0,0,4,4", "-q"],
        ["eval", synth_nbtf, "--reference", synth_stack, "-o", report, "--blur-images", "-1", "-q"],
        ["eval", synth_nbtf, "--reference", synth_stack, "-o", synth_stack, "-q"])
    with pytest.raises(FileNotFoundError) as e:
        nbtf.evaluate(missing, synth_stack, quiet=True)
    assert str(e.value) == wants[0]
    with pytest.raises(ValueError) as e:
        nbtf.evaluate(synth_nbtf, synth_stack, crop=(0, 0, 4, 4), quiet=True)
    assert str(e.value) == wants[1]
    with pytest.raises(ValueError) as e:
        nbtf.evaluate(synth_nbtf, synth_stack, blur_images=-1, quiet=True)
    assert str(e.value) == wants[2]
    with pytest.raises(ValueError) as e:
        nbtf.evaluate(synth_nbtf, synth_stack, output=synth_stack, quiet=True)
    assert str(e.value) == wants[3]


def test_ctrl_c_stops_after_a_checkpoint(synth_stack, tmp_path):
    # A run far too long to finish, checkpointing every 0.2 s; SIGINT once training has started.
    import signal
    import subprocess
    import sys
    import time

    config = tmp_path / "long.json"
    config.write_text(json.dumps({
        "optimizer": {"name": "adam", "learning_rate": 0.003},
        "training": {"batch_size": 1024, "images_per_input": 64, "min_steps": 0, "min_steps_per_input": 0,
                     "epochs": 1000000, "checkpoint_seconds": 0.2}}))
    out = tmp_path / "long.nbtf"
    code = """
import sys, nbtf
try:
    nbtf.compress(sys.argv[1], sys.argv[2], clusters=4, config=sys.argv[3], seed=1, threads=1, quiet=True)
except KeyboardInterrupt as e:
    print(e)
    sys.exit(3)
"""
    p = subprocess.Popen([sys.executable, "-c", code, synth_stack, str(out), str(config)], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    checkpoint = tmp_path / "long.nbtf.ckpt"
    deadline = time.monotonic() + 120
    while not checkpoint.exists() and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.1)
    p.send_signal(signal.SIGINT)
    stdout, stderr = p.communicate(timeout=120)
    assert p.returncode == 3, stderr
    assert f"nothing written to {out}. Training state is in {checkpoint}: call compress again with resume=True" in stdout
    assert not out.exists() and checkpoint.exists()


def _tree(root):
    """Every file under root with its bytes, every folder, links not followed."""
    out = {}
    for folder, dirs, files in os.walk(root):
        out[folder] = "folder"
        for name in files:
            path = os.path.join(folder, name)
            with open(path, "rb") as f:
                out[path] = f.read()
    return out


def test_no_output_lands_on_an_input(synth_stack, synth_nbtf, tmp_path):
    # The command line's guard (util/path_guard.h), for every output of the module's functions:
    # inside the stack, through a link to it or to one of its images, onto the file read.
    image = next(os.path.join(d, f) for d, _, fs in sorted(os.walk(synth_stack)) for f in sorted(fs) if f.endswith(".png"))
    linked = tmp_path / "linked"
    linked.symlink_to(synth_stack)
    image_link = tmp_path / "image.png"
    image_link.symlink_to(image)
    before = _tree(synth_stack)
    nbtf_before = open(synth_nbtf, "rb").read()
    inside = [image, os.path.join(synth_stack, "new.nbtf"), linked / os.path.relpath(image, synth_stack), image_link]
    cases = [(lambda out: nbtf.compress(synth_stack, out, **QUICK), out) for out in inside]
    cases += [(lambda out: nbtf.compress(synth_stack, tmp_path / "ok.nbtf", stats_json=out, **QUICK), out) for out in inside]
    cases += [(lambda out: nbtf.compress(synth_stack, tmp_path / "ok.nbtf", save_encoder=out, **QUICK), out) for out in inside]
    folders = [os.path.join(synth_stack, "report"), linked / "report", synth_stack]
    cases += [(lambda out: nbtf.evaluate(synth_nbtf, synth_stack, output=out, quiet=True), out) for out in folders]
    cases += [(lambda out: nbtf.evaluate(synth_nbtf, synth_stack, output=out, quiet=True), out)
              for out in (synth_nbtf, os.path.dirname(synth_nbtf))]
    for call, out in cases:
        with pytest.raises(ValueError, match="nothing was written"):
            call(out)
    assert _tree(synth_stack) == before
    assert open(synth_nbtf, "rb").read() == nbtf_before
    assert not (tmp_path / "ok.nbtf").exists()
