"""benchmarks/_context.py: the header, timer and speed-up flag of every benchmark (issue 33.4)."""

from __future__ import annotations

import importlib.util
import io
import os
import re
import sys
import time
from pathlib import Path

import pytest

_PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "_context.py"


@pytest.fixture(scope="module")
def ctxmod():
    spec = importlib.util.spec_from_file_location("_bench_context", _PATH)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # dataclasses resolve their module by name
    spec.loader.exec_module(mod)
    yield mod
    sys.modules.pop(spec.name, None)


def test_header_shows_load_cores_blas_threads_and_direct_backends(ctxmod, monkeypatch):
    monkeypatch.setattr(ctxmod, "load_average", lambda: (3.25, 2.5, 1.75))  # a made-up load
    monkeypatch.setattr(ctxmod, "usable_cores", lambda: 3)  # a made-up affinity mask
    buf = io.StringIO()
    ctx = ctxmod.header(file=buf, case="unit test")
    text = buf.getvalue()
    assert "# load average: 3.25 2.50 1.75" in text
    assert "# usable cores: 3 " in text
    assert re.search(r"^# BLAS: .*\S", text, re.M), text
    assert re.search(r"^# pdlin threads: \d+", text, re.M), text
    # superlu ships with scipy, so it is always installed
    assert re.search(r"^# direct backends: installed superlu", text, re.M), text
    assert re.search(r"'auto' at >= \d+ unknowns: symmetric -> \w+", text), text
    assert "# case: unit test" in text
    import numpy as np
    import scipy

    assert f"numpy {np.__version__}" in text and f"scipy {scipy.__version__}" in text
    assert ctx.load1 == 3.25 and ctx.cores == 3


def test_header_follows_pdlin_threads(ctxmod):
    import pdlin

    pdlin.set_num_threads(1)
    try:
        assert ctxmod.collect().pdlin_threads.startswith("1 (pdlin.set_num_threads)")
    finally:
        pdlin.set_num_threads(None)


def test_real_machine_values(ctxmod):
    assert ctxmod.usable_cores() == len(os.sched_getaffinity(0))
    la = ctxmod.load_average()
    assert la is None or (len(la) == 3 and all(x >= 0 for x in la))


@pytest.mark.parametrize(
    ("k", "load", "cores", "flagged"),
    [
        (2, 0.0, 2, False),  # idle machine, both cores used: load 0 is not > 0 free cores
        (2, 0.01, 2, True),  # any competing load on a fully used machine
        (2, 1.9, 4, False),  # 2 cores free, load below them
        (2, 2.0, 4, False),  # load equal to the free cores: not exceeding
        (2, 2.1, 4, True),
        (1, 0.5, 2, False),
        (1, 1.5, 2, True),
        (4, 0.0, 2, True),  # more workers than cores
    ],
)
def test_speedup_flag(ctxmod, k, load, cores, flagged):
    note = ctxmod.speedup_flag(k, load=load, cores=cores)
    assert bool(note) == flagged, note
    if flagged:
        assert note.startswith("unreliable (")
    if flagged and k <= cores:
        assert f"load {load:.2f} > free cores {cores - k}" in note


def test_speedup_flag_defaults_to_now(ctxmod, monkeypatch):
    monkeypatch.setattr(ctxmod, "load_average", lambda: (5.0, 0.0, 0.0))
    monkeypatch.setattr(ctxmod, "usable_cores", lambda: 4)
    assert ctxmod.speedup_flag(2) == "unreliable (load 5.00 > free cores 2)"
    monkeypatch.setattr(ctxmod, "load_average", lambda: None)  # no load average: no claim
    assert ctxmod.speedup_flag(2) == ""


def test_timed_returns_wall_and_cpu(ctxmod):
    with ctxmod.timed() as idle:
        time.sleep(0.2)
    assert idle.wall >= 0.2 and idle.cpu < 0.1  # sleeping uses wall, not CPU
    with ctxmod.timed() as busy:
        t0 = time.process_time()
        while time.process_time() - t0 < 0.1:
            pass
    assert busy.cpu >= 0.1 and busy.wall > 0
    assert "s wall" in str(busy) and "s CPU" in str(busy)


def test_timed_counts_waited_children(ctxmod):
    import subprocess

    code = "import time\nt=time.process_time()\nwhile time.process_time()-t<0.2: pass"
    with ctxmod.timed() as t:
        subprocess.run([sys.executable, "-c", code], check=True)
    assert t.cpu >= 0.2  # the child's 0.2 s of CPU


def test_backend_label(ctxmod):
    import numpy as np
    import scipy.sparse as sp

    from pdlin.solvers import DirectSolver, solve_linear

    A = sp.csr_array(np.array([[4.0, 1.0], [1.0, 3.0]]))
    out = solve_linear(A, np.ones(2), "direct")
    used = out.info["direct_backend"]
    assert ctxmod.backend_label(out) == used
    assert ctxmod.backend_label(out.info) == used
    assert ctxmod.backend_label({"info": out.info}) == used
    assert ctxmod.backend_label(DirectSolver(A, backend="superlu")) == "superlu"
    assert ctxmod.backend_label({}, default="-") == "-"
