"""Placement in large scenes: wall time and peak memory of ``scenescore place`` for 50, 100 and 200 objects.

    python benchmarks/bench_large_scene.py [--sizes 50,100,200] [--unknown 3] [--iterations 60]

A small model is trained on dining scenes (``--iterations``, a few seconds; the numbers measure memory
and time, not placement quality) and saved. Each scene tiles place settings (a plate, a fork and a knife
either side, a bowl above) on a grid, every object inside the bounds and apart from the others; the
last ``--unknown`` objects have ``pose: null``. Each size runs ``scenescore place`` (the default
options: 64 particles from the best of 2048 candidates) in a child process; its peak resident memory
is the child's own ``ru_maxrss``. The target: 200 objects within 2 GB.
"""

from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from scenescore.learn import TrainConfig, fit
from scenescore.scenarios import DiningScenario
from scenescore.scenarios.dining import CATALOGUE
from scenescore.scene.scene import Scene, SceneObject

CELL = 0.5  # m, one place setting per cell
# (category, offset in the cell, heading): disjoint footprints, all inside the cell
SETTING = [
    ("plate", (0.0, -0.05), 0.0),
    ("fork", (-0.19, -0.05), math.pi / 2),
    ("knife", (0.19, -0.05), math.pi / 2),
    ("bowl", (0.0, 0.16), 0.0),
]
LIMIT_GB = 2.0


def large_scene(n: int, unknown: int) -> Scene:
    """``n`` objects in place settings on a grid; the last ``unknown`` of them with no pose."""
    settings = math.ceil(n / len(SETTING))
    cols = math.ceil(math.sqrt(settings))
    rows = math.ceil(settings / cols)
    x0, y0 = -cols * CELL / 2, -rows * CELL / 2
    objects = []
    for k in range(n):
        s, (cat, (dx, dy), th) = divmod(k, len(SETTING))[0], SETTING[k % len(SETTING)]
        r, c = divmod(s, cols)
        size, color, shape = CATALOGUE[cat]
        pose = (x0 + (c + 0.5) * CELL + dx, y0 + (r + 0.5) * CELL + dy, th)
        objects.append(
            SceneObject(f"{cat}_{s}", cat, size, None if k >= n - unknown else pose, color, shape=shape)
        )
    return Scene(objects, bounds=((x0, y0), (-x0, -y0)))


def run_place(model: Path, scene: Path, out: Path) -> tuple[float, float, int, str]:
    """``scenescore place`` in a child process: wall seconds, peak RSS in GB, exit status, last stderr line."""
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    cmd = [sys.executable, "-m", "scenescore", "place", str(model), str(scene), "--out", str(out), "--quiet"]
    t = time.perf_counter()
    child = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    assert child.stderr is not None
    err = child.stderr.read()
    _, status, usage = os.wait4(child.pid, 0)
    dt = time.perf_counter() - t
    child.returncode = os.waitstatus_to_exitcode(status)
    last = err.strip().splitlines()[-1] if err.strip() else ""
    return dt, usage.ru_maxrss * 1024 / 1e9, child.returncode, last  # ru_maxrss is in KiB on Linux


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="50,100,200", help="numbers of objects, comma-separated")
    ap.add_argument("--unknown", type=int, default=3, help="objects with pose: null in each scene")
    ap.add_argument("--iterations", type=int, default=60, help="training iterations of the small model")
    args = ap.parse_args(argv)
    sizes = [int(s) for s in args.sizes.split(",")]
    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        model = fit(DiningScenario().generate(24, 0), TrainConfig(iterations=args.iterations), progress=False)
        path = Path(tmp) / "model.ckpt"
        model.save(path)
        c = model.config
        print(
            f"model: dining, {args.iterations} iterations ({time.perf_counter() - t:.1f} s), hidden {c.hidden}, "
            f"{c.layers} layers, walls {c.walls}; place: 64 particles, 2048 candidates; "
            f"{os.cpu_count()} CPU(s), SCENESCORE_MEMORY_GB={os.environ.get('SCENESCORE_MEMORY_GB', 'unset')}"
        )
        print("| objects | unknown | wall s | peak RSS GB | within 2 GB | exit |")
        print("|---:|---:|---:|---:|:---:|---|")
        for n in sizes:
            scene = Path(tmp) / f"scene_{n}.json"
            large_scene(n, args.unknown).to_json(scene)
            dt, gb, rc, last = run_place(path, scene, Path(tmp) / f"placed_{n}.json")
            exit_text = "0" if rc == 0 else f"{rc}: {last[:80]}"
            ok = "yes" if gb <= LIMIT_GB else "no"
            print(f"| {n} | {args.unknown} | {dt:.1f} | {gb:.2f} | {ok} | {exit_text} |", flush=True)


if __name__ == "__main__":
    main()
