"""First-run and warm wall times of every gallery scene (``pdlin run --example NAME``).

Each scene runs in a fresh process twice: first with an empty numba cache (a new
``XDG_CACHE_HOME``, so pdlin's kernels are compiled, as on a user's first run after
installing), then again with the cache that run left (warm: kernels loaded from disk).
Both runs pay Python's and pdlin's import. The table prints scene, first-run s, warm s (each
with the child's CPU seconds beside it) and their ratio, after the context header (load
average, usable cores, BLAS; the numbers depend on what else runs)::

    python benchmarks/bench_first_run.py                 # every scene
    python benchmarks/bench_first_run.py bar lps_cube    # some
    PDLIN_NUMBA=0 python benchmarks/bench_first_run.py   # without numba

The issue-31 goal: first run <= 2 x warm or <= 10 s.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _context import Timing, header, timed  # noqa: E402


def scenes() -> list[str]:
    """The gallery's scene names (``pdlin.scene``'s built-in examples)."""
    out = subprocess.run(
        [sys.executable, "-m", "pdlin.cli.main", "examples"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    return [ln.split()[0] for ln in out.splitlines() if ln[:1].isalpha() and " " in ln][:-1]


def run_once(name: str, cache: str, out_dir: str) -> Timing:
    """Wall and CPU seconds of one ``pdlin run --example name`` in a new process."""
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env["XDG_CACHE_HOME"] = cache
    args = [sys.executable, "-m", "pdlin.cli.main", "run", "--example", name]
    args += ["--output", os.path.join(out_dir, f"{name}.vtu")]
    with timed() as t:
        res = subprocess.run(args, env=env, capture_output=True, text=True, cwd=out_dir)
    if res.returncode != 0:
        raise RuntimeError(f"{name}: exit {res.returncode}\n{res.stdout}\n{res.stderr}")
    return t


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("names", nargs="*", help="scenes (default: all of `pdlin examples`)")
    ap.add_argument("--warm-runs", type=int, default=1, help="warm runs (the fastest counts)")
    args = ap.parse_args(argv)
    header()
    names = args.names or scenes()
    print(
        f"{'scene':<20} {'first s':>8} {'CPU s':>8} {'warm s':>8} {'CPU s':>8} {'ratio':>6}  "
        "goal (<= 2x or <= 10 s)"
    )
    worst = 0.0
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            cache = tempfile.mkdtemp(dir=tmp)  # empty: nothing compiled yet
            t1 = run_once(name, cache, tmp)
            runs = [run_once(name, cache, tmp) for _ in range(max(1, args.warm_runs))]
            tw = min(runs, key=lambda t: t.wall)
            first, warm = t1.wall, tw.wall
            ok = first <= 2.0 * warm or first <= 10.0
            worst = max(worst, first / warm)
            print(
                f"{name:<20} {first:8.2f} {t1.cpu:8.2f} {warm:8.2f} {tw.cpu:8.2f} "
                f"{first / warm:6.2f}  "
                f"{'ok' if ok else 'MISSED'}",
                flush=True,
            )
    print(f"load average (1, 5, 15 min): {os.getloadavg()}; numba: {_numba()}")


def _numba() -> str:
    if os.environ.get("PDLIN_NUMBA", "").strip() == "0":
        return "off (PDLIN_NUMBA=0)"
    try:
        import numba
    except ImportError:
        return "not installed"
    return numba.__version__


if __name__ == "__main__":
    main()
