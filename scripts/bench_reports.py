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
