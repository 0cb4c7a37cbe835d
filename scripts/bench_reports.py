"""What the benchmarks built on compress_and_eval (scripts/lib.sh) read back: each run's
summary (--stats-json) and evaluation report, and their Markdown tables."""
import json
import os


def load(path):
    with open(path) as f:
        return json.load(f)


def runs_of(out, preset):
    """label -> (stats, report) for every run of `preset` in `out` that has both."""
    runs = {}
    for name in sorted(os.listdir(out)):
        if name.startswith(preset + "-") and name.endswith(".stats.json"):
            label = name[len(preset) + 1:-len(".stats.json")]
            report = os.path.join(out, f"{preset}-{label}", "report.json")
            if os.path.exists(report):
                runs[label] = (load(os.path.join(out, name)), load(report))
    return runs


def markdown_table(head, rows):
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(lines)


# The error columns every quality benchmark prints: against the stack and against the float
# ground truth nbtf-synth writes beside it, all images and held-out images.
TRUTH_HEAD = ["RMSE vs stack", "held-out vs stack", "RMSE vs truth", "held-out vs truth"]
TRUTH_NOTE = ("RMSE: linear RGB / alpha (eq. 10); vs stack: against the stored 8-bit images; vs truth: against the "
              "float ground truth nbtf-synth wrote beside them; held-out: the 10% of images kept out of training. The "
              "stack row is the stack itself against the truth: the noise floor (JPEG: mostly the JPEG's loss; PNG: "
              "the 8-bit steps). A model closer to the stack than to the truth has learned part of that noise.")


def _cell(value):
    return "-" if value is None else f"{value:.5f}"


def truth_cells(report):
    """The four TRUTH_HEAD cells of one evaluation report."""
    return [_cell(report.get(k)) for k in ("rmse", "rmse_holdout", "rmse_ground_truth", "rmse_ground_truth_holdout")]


def noise_floor_row(preset, report, before, after):
    """The stack against its ground truth as a table row: preset, run name, `before` empty
    cells, the four TRUTH_HEAD cells (0 against itself), `after` empty cells."""
    return ([preset, "stack (noise floor)"] + ["-"] * before +
            ["0", "0", _cell(report.get("rmse_reference_vs_ground_truth")),
             _cell(report.get("rmse_reference_vs_ground_truth_holdout"))] + ["-"] * after)


def dominance_verdict(ours, rivals, key, low, high):
    """nbtf's rate-distortion curve below the rivals' across the window: every rival (label ->
    (stats, report)) of ratio in [low, high] is beaten, on report[key], by one of `ours` of that
    ratio or higher (a file of that size or smaller). Returns the verdict text ending in PASS or
    FAIL; the failure names the first rival, by ratio, that no point of ours beats."""
    def points(runs):
        return [(s["ratio"], r[key], l) for l, (s, r) in runs.items() if r.get(key) is not None]
    mine = points(ours)
    for ratio, error, label in sorted(p for p in points(rivals) if low <= p[0] <= high):
        best = min(((e, l) for x, e, l in mine if x >= ratio), default=None)
        if best is None or best[0] >= error:
            ours_text = "none" if best is None else f"{best[0]:.5f} ({best[1]})"
            return (f"at 1:{ratio:.0f} nbtf's best point of that size or smaller has {key} {ours_text} against "
                    f"{label}'s {error:.5f} FAIL")
    return (f"every PCA and per-texel point from 1:{low} to 1:{high} is beaten by an nbtf point of its size or "
            f"smaller ({key}) PASS")
