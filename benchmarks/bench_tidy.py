"""The README's tidy example as a user runs it: whole-process wall seconds, with a core to spare and on one.

    python benchmarks/bench_tidy.py [--runs 5] [--model model.ckpt]

Runs ``scenescore tidy model.ckpt examples/messy_dining.json --out tidy.json --plot tidy.png`` (start-up,
imports and the plot included) ``--runs`` times as it is and as many times with ``--threads 1``, in turn
(default, one thread, default, ...), so that a machine whose speed drifts slows both alike; prints the min,
median and max wall seconds of each, the median of the paired ratios, and whether every run wrote the same
``tidy.json`` to the byte. With ``--threads 1`` tidy places the moved objects after its selection; by
default, on a machine with a second core to spare, it places the set chosen so far on that core while the
selection's last rounds go on (:class:`scenescore.runtime.ahead.Ahead`). The model (``--model``; default: trained
first as the README does, 48 generated dining scenes and 150 iterations) is not timed.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from profile_experiment import readme_model  # this folder's script: the README's model, trained as it says

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "messy_dining.json"


def timed(model: Path, folder: Path, extra: list[str]) -> tuple[float, bytes]:
    """One run of the README's command (plus ``extra``): its wall seconds and the ``tidy.json`` it wrote."""
    out = folder / "tidy.json"
    out.unlink(missing_ok=True)
    cmd = [sys.executable, "-m", "scenescore", "tidy", str(model), str(EXAMPLE)]
    cmd += ["--out", str(out), "--plot", str(folder / "tidy.png"), "--quiet", *extra]
    t = time.perf_counter()
    done = subprocess.run(cmd, cwd=folder, capture_output=True, text=True)
    wall = time.perf_counter() - t
    if done.returncode != 0:
        raise SystemExit(f"bench_tidy: {' '.join(cmd)} failed ({done.returncode}):\n{done.stderr[-2000:]}")
    return wall, out.read_bytes()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5, help="runs of each setting (default 5)")
    ap.add_argument("--model", type=Path, default=None, help="the checkpoint (default: trained first)")
    args = ap.parse_args()
    if args.runs < 1:
        raise SystemExit(f"bench_tidy: --runs: expected at least 1, got {args.runs}")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        if args.model:
            model = args.model.resolve()
        else:
            with contextlib.redirect_stdout(io.StringIO()):  # the table is what this prints
                model = readme_model(folder)
        timed(model, folder, [])  # warm-up: the file cache, not counted
        walls: dict[str, list[float]] = {"default": [], "--threads 1": []}
        outputs = set()
        for _ in range(args.runs):
            for label, extra in (("default", []), ("--threads 1", ["--threads", "1"])):
                wall, out = timed(model, folder, extra)
                walls[label].append(wall)
                outputs.add(out)
    print(f"scenescore tidy model.ckpt {EXAMPLE.relative_to(ROOT)} --out tidy.json --plot tidy.png")
    print(f"{args.runs} runs each, in turn; whole-process wall seconds\n")
    print("| setting | min | median | max |")
    print("|---|---:|---:|---:|")
    for label, w in walls.items():
        print(f"| {label} | {min(w):.2f} | {statistics.median(w):.2f} | {max(w):.2f} |")
    ratios = [a / b for a, b in zip(walls["default"], walls["--threads 1"])]
    print(f"\ndefault / --threads 1, paired: median {statistics.median(ratios):.2f}")
    print(f"tidy.json the same in every run: {'yes' if len(outputs) == 1 else 'NO'}")


if __name__ == "__main__":
    main()
