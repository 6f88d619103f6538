"""numba's disk cache notices an edit of any simulator file (``compiled/cache.py``): without it,
a cached kernel keeps the code of the callees and constants it took from other files."""

import importlib
import json
import shutil
import sys
from pathlib import Path

from numba.core.dispatcher import Dispatcher

from rigid_env.sim.compiled import backend, cache, first_call

SIM = Path(cache.__file__).resolve().parents[1]


def kernels():
    for name in backend.KERNEL_MODULES:
        module = importlib.import_module(f"rigid_env.sim.compiled.{name}")
        for value in vars(module).values():
            if isinstance(value, Dispatcher) and value.__module__ == module.__name__:
                yield value


def test_every_cached_kernel_is_stamped_with_the_simulator_sources():
    found = list(kernels())
    assert len(found) > 20  # every kernel module was visited
    for kernel in found:
        stamp = kernel._cache._impl._locator.get_source_stamp()
        assert stamp[1] == cache.sources_hash(), kernel


def test_the_stamp_changes_with_any_simulator_source(tmp_path):
    copy = tmp_path / "sim"
    shutil.copytree(SIM, copy, ignore=shutil.ignore_patterns("__pycache__"))
    before = cache.sources_hash(copy)
    assert cache.sources_hash(copy) == before
    # A file in a cache directory is no source: the stamp stays.
    (copy / "compiled" / "__pycache__" / "rigid_env").mkdir(parents=True)
    (copy / "compiled" / "__pycache__" / "rigid_env" / "stray.py").write_text("x = 1\n")
    assert cache.sources_hash(copy) == before
    # A constant a kernel reads from another package (the solve's Newton steps).
    settings = copy / "contacts" / "settings.py"
    settings.write_text(settings.read_text() + "\nNEWTON_STEPS = 9\n")
    assert cache.sources_hash(copy) != before


def test_functions_outside_the_package_keep_numbas_locator(tmp_path, monkeypatch):
    (tmp_path / "outside_kernel.py").write_text(
        "from numba import njit\n\n\n@njit(cache=True)\ndef f(x):\n    return x + 1\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    module = importlib.import_module("outside_kernel")
    try:
        locator = module.f._cache._impl._locator
        assert not getattr(locator, "rigid_env_locator", False)
        assert module.f(1) == 2
    finally:
        sys.modules.pop("outside_kernel", None)


PROBE = """
from rigid_env import sim
scene = sim.Scene(sim.Body.box((0.1, 0.2, 0.3), 2.0), 0.01, backend="compiled")
scene.step(scene.initial_state(angular_velocity=(0.1, 3.0, 0.1)))
stats = scene._driver.step.stats
print(len(stats.cache_hits), len(stats.cache_misses))
"""


def test_a_second_process_loads_the_compiled_step_from_the_cache(tmp_path):
    """The stamp must be stable across processes: a stamp that moved with every compile (a
    hash that took in the files of a cache directory inside the package, where the compile
    locks live by default) recompiles every run. The locks go to a fresh directory inside the
    package, as by default; numba's cache to an empty one, so the first run compiles."""
    import os
    import subprocess
    import uuid

    drivers = SIM / "compiled" / "__pycache__" / f"test-drivers-{uuid.uuid4().hex}"
    env = {
        **os.environ,
        "RIGID_ENV_CACHE_DIR": str(drivers),
        "NUMBA_CACHE_DIR": str(tmp_path / "numba"),
    }
    try:
        runs = [
            subprocess.run(
                [sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, check=True
            ).stdout.split()
            for _ in range(2)
        ]
    finally:
        shutil.rmtree(drivers, ignore_errors=True)
    assert runs[0] == ["0", "1"]  # compiled, then saved
    assert runs[1] == ["1", "0"]  # loaded


def test_importing_the_simulator_does_not_import_numba():
    """The locator is installed by the first kernel module that compiles (``cache.njit``), not at
    import: a numpy-backend user does not pay numba's import (~0.5 s)."""
    import subprocess

    code = "import sys, rigid_env.sim; print('numba' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False"]


def probe_env(tmp_path, drivers):
    import os

    return {
        **os.environ,
        "RIGID_ENV_CACHE_DIR": str(drivers),
        "NUMBA_CACHE_DIR": str(tmp_path / "numba"),
    }


def test_a_compile_is_announced_once_and_a_load_is_not(tmp_path):
    """A process that compiles says so on stderr before it starts (``first_call``), with the
    usual duration; a process that loads says nothing; the first compile's time is recorded and
    quoted the next time a step of that kind compiles."""
    import subprocess

    drivers = tmp_path / "drivers"
    env = probe_env(tmp_path, drivers)
    runs = [
        subprocess.run(
            [sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, check=True
        )
        for _ in range(2)
    ]
    first, second = (run.stderr.strip().splitlines() for run in runs)
    assert len(first) == 1, first
    assert "compiling the simulator's step" in first[0]
    usual = first_call.USUAL_SECONDS["free"]
    assert f"about {usual:.0f} s with empty caches" in first[0]
    assert second == []
    times = json.loads((drivers / "compile_times.json").read_text())
    assert set(times) == {"free"} and times["free"] > 0
    # A new composition of the same kind (another integrator) quotes the recorded time.
    other = PROBE.replace("backend=", 'integrator="rk4", backend=')
    third = subprocess.run(
        [sys.executable, "-c", other], env=env, capture_output=True, text=True, check=True
    ).stderr
    assert f"(it took {times['free']:.0f} s the last time here)" in third, third


def test_processes_that_start_together_compile_once(tmp_path):
    """Three processes on an empty cache: one compiles, the others wait on the step's lock and
    then load what it cached (without the lock each finds the cache empty and compiles)."""
    import subprocess

    env = probe_env(tmp_path, tmp_path / "drivers")
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", PROBE],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for _ in range(3)
    ]
    outs = [proc.communicate(timeout=600) for proc in procs]
    assert [proc.returncode for proc in procs] == [0, 0, 0], outs
    compiled = [out for out, err in outs if "compiling the simulator's step" in err]
    assert len(compiled) == 1, outs
    assert compiled[0].split() == ["0", "1"]
    loaded = [out.split() for out, err in outs if "compiling the simulator's step" not in err]
    assert loaded == [["1", "0"], ["1", "0"]]


def test_numbas_index_and_data_files_are_written_under_the_directory_lock(tmp_path):
    """``cache.install`` wraps numba's ``IndexDataCacheFile.save`` (and ``load``) in a lock per
    cache directory: while another holder has it, a save writes nothing; released, the save
    completes with the index naming its data file."""
    import fcntl
    import threading

    from numba.core import caching

    assert cache.install()
    files = caching.IndexDataCacheFile(str(tmp_path), "probe", ("stamp",))
    with open(tmp_path / "index.lock", "a+b") as holder:
        fcntl.flock(holder, fcntl.LOCK_EX)
        saver = threading.Thread(target=files.save, args=(("key",), b"machine code"))
        saver.start()
        saver.join(timeout=0.5)
        assert saver.is_alive(), "the save went ahead while the lock was held"
        assert not (tmp_path / "probe.nbi").exists()
        fcntl.flock(holder, fcntl.LOCK_UN)
    saver.join(timeout=60)
    assert not saver.is_alive()
    assert files.load(("key",)) == b"machine code"
