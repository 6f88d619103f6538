"""The compile helper: a second process compiles some kernels of a cold first step into the
shared cache, each kernel taken by one process only (its lock), largest first."""

from __future__ import annotations

import json
import os
import pickle
import subprocess
import sys

import numba
import pytest

from rigid_env.sim.compiled import compile_helper, contact_solve
from rigid_env.sim.compiled.contact_gauss_seidel import gauss_seidel
from rigid_env.sim.scenes import landing_scene


@pytest.fixture
def landing_callees(monkeypatch):
    """The (module, name, data) of the two smallest kernels a landing step calls by address."""
    monkeypatch.setenv("RIGID_ENV_BACKEND", "compiled")
    scene, _ = landing_scene(dt=0.01)
    callees = [(k.module, k.name, data) for k, data in scene._driver._callees]
    wanted = {"detect", "assemble"}
    return [c for c in callees if c[1] in wanted]


@numba.njit
def _helper(x):
    return 2.0 * x


@numba.njit
def _caller(x):
    return _helper(x) + _helper(x + 1.0)


def _own(f) -> int:
    return len(f.py_func.__code__.co_code)


def test_compile_size_counts_each_reached_helper_once():
    assert compile_helper.compile_size(_helper) == _own(_helper)
    assert compile_helper.compile_size(_caller) == _own(_caller) + _own(_helper)
    # The contact solve reaches its helpers (gauss_seidel directly and through converge).
    solve = compile_helper.compile_size(contact_solve.solve)
    assert solve > _own(contact_solve.solve) + _own(gauss_seidel)


def test_a_kernel_another_process_holds_is_skipped_then_taken(landing_callees, tmp_path):
    """A kernel whose lock is held is left for the end (the other process compiles it); the
    rest get their addresses."""
    held = landing_callees[0]
    with compile_helper._holding(tmp_path / f"{held[0]}.{held[1]}.lock", wait=True):
        out = [0] * len(landing_callees)
        skipped = compile_helper._visit(landing_callees, tmp_path, out)
    assert skipped == [0]
    assert out[0] == 0 and all(a != 0 for a in out[1:])
    # Once free, ``addresses`` takes it (here from this process's own compile).
    assert all(a != 0 for a in compile_helper.addresses(landing_callees, tmp_path))


_LOAD = """
import json, pickle, sys
from rigid_env.sim.compiled import compile_helper
callees = pickle.load(open(sys.argv[1], "rb"))
compile_helper.addresses(callees, compile_helper.Path(sys.argv[2]))
functions = compile_helper._functions(callees)
print(json.dumps([[sum(f.stats.cache_hits.values()), sum(f.stats.cache_misses.values())]
                  for f in functions]))
"""


def test_what_the_helper_compiles_a_later_process_loads(landing_callees, tmp_path):
    """The helper process (``python -m rigid_env.sim.compiled.compile_helper``) caches every
    kernel it is given: a process started after it, on the same empty-at-first caches and with
    no helper of its own, loads each of them and compiles none."""
    env = {
        **os.environ,
        "NUMBA_CACHE_DIR": str(tmp_path / "numba"),
        "RIGID_ENV_CACHE_DIR": str(tmp_path / "drivers"),
        compile_helper.ENV: "0",
    }
    (tmp_path / "drivers").mkdir()
    payload = pickle.dumps(landing_callees)
    helper = [sys.executable, "-m", compile_helper.__name__]
    subprocess.run(helper, input=payload, env=env, check=True, timeout=600)
    (tmp_path / "callees.pkl").write_bytes(payload)
    out = subprocess.run(
        [sys.executable, "-c", _LOAD, str(tmp_path / "callees.pkl"), str(tmp_path / "drivers")],
        env=env, capture_output=True, text=True, check=True, timeout=600,
    )  # fmt: skip
    counts = json.loads(out.stdout.strip().splitlines()[-1])
    assert counts == [[1, 0]] * len(landing_callees)
