# The benchmarks' table and verdict helpers (scripts/bench_reports.py): the columns against the
# stack and the ground truth, the noise-floor row, and the dominance check of the frontier.
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))), "scripts"))
from bench_reports import TRUTH_HEAD, dominance_verdict, noise_floor_row, truth_cells  # noqa: E402


def run(ratio, truth, held=None):
    return ({"ratio": ratio}, {"rmse": truth - 0.002, "rmse_holdout": None, "rmse_ground_truth": truth,
                               "rmse_ground_truth_holdout": held})


def test_truth_cells_and_the_noise_floor_row():
    _, report = run(1000, 0.03, 0.031)
    report["rmse_reference_vs_ground_truth"] = 0.0186
    report["rmse_reference_vs_ground_truth_holdout"] = 0.01855
    assert truth_cells(report) == ["0.02800", "-", "0.03000", "0.03100"]
    row = noise_floor_row("fabric", report, 2, 3)
    assert len(row) == 2 + 2 + len(TRUTH_HEAD) + 3
    assert row[:2] == ["fabric", "stack (noise floor)"]
    assert row[4:8] == ["0", "0", "0.01860", "0.01855"]


def test_dominance_passes_when_a_smaller_nbtf_file_beats_every_larger_rival():
    ours = {"nbtf_a": run(20000, 0.024), "nbtf_b": run(500, 0.020)}
    rivals = {"pca_64": run(100, 0.025), "pca_8": run(800, 0.035)}
    assert dominance_verdict(ours, rivals, "rmse_ground_truth", 100, 20000).endswith("PASS")


def test_dominance_names_the_ratio_and_the_rival_that_wins():
    ours = {"nbtf_a": run(10000, 0.030)}
    rivals = {"pca_64": run(103, 0.027)}
    text = dominance_verdict(ours, rivals, "rmse_ground_truth", 100, 20000)
    assert text.endswith("FAIL")
    assert "1:103" in text and "pca_64" in text and "0.02700" in text
    # Without held-out figures there is nothing to compare on that key: no rival, so no failure.
    assert dominance_verdict(ours, rivals, "rmse_ground_truth_holdout", 100, 20000).endswith("PASS")


def test_dominance_asks_each_rival_for_an_nbtf_point_no_larger_and_lower():
    # The curve below the rivals': PCA at 1:103 beaten by the 1:200 point, the per-texel model at
    # 1:4147 by the 1:10000 one. The 1:10000 point need not beat PCA's far larger file.
    ours = {"nbtf_small": run(10000, 0.034), "nbtf_big": run(200, 0.023)}
    rivals = {"pca_64": run(103, 0.027), "per_texel": run(4147, 0.036), "pca_1": run(50000, 0.001)}
    assert dominance_verdict(ours, rivals, "rmse_ground_truth", 100, 20000).endswith("PASS")  # pca_1: outside
    rivals["per_texel"] = run(4147, 0.0334)
    text = dominance_verdict(ours, rivals, "rmse_ground_truth", 100, 20000)
    assert text.endswith("FAIL") and "1:4147" in text and "per_texel" in text and "0.03400 (nbtf_small)" in text
