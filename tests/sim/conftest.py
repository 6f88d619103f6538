"""Every sim test runs on both backends: the numpy reference and the compiled kernels.

The ``sim_backend`` fixture is autouse and parametrised per test as ``[numpy]`` and
``[compiled]``: it sets ``RIGID_ENV_BACKEND`` for the scenes a test builds (``numpy``, or
``auto``, which compiles every scene whose stages all have kernels and runs the rest on numpy).
A scene that passes ``backend=`` itself keeps it. The modules that choose their backends
themselves, or test no step, run once.
"""

import pytest

BACKENDS = ("numpy", "compiled")
NUMPY_ONLY = {
    "test_compiled.py": "compares the backends itself (explicit backend= everywhere)",
    "test_compiled_contacts.py": "compares the backends itself (explicit backend= everywhere)",
    "test_compiled_pairs.py": "compares the backends itself (explicit backend= everywhere)",
    "test_compiled_cache.py": "tests numba's cache, not a step",
    "test_compile_helper.py": "tests the compile helper, not a step",
    "test_disable_jit.py": "runs the compiled kernels as Python itself (backend set explicitly)",
    "test_pair_detection.py": "tests the pair detection kernels, which both backends call",
    "test_min_norm.py": "tests one compiled kernel against numpy's pinv, not a step",
    "test_parameters.py": "per-element parameters are the compiled step's (backend= explicit)",
}


def pytest_generate_tests(metafunc):
    if "sim_backend" in metafunc.fixturenames:
        only = metafunc.definition.path.name in NUMPY_ONLY
        metafunc.parametrize("sim_backend", ("numpy",) if only else BACKENDS, indirect=True)


@pytest.fixture(autouse=True)
def sim_backend(request, monkeypatch):
    backend = request.param
    monkeypatch.setenv("RIGID_ENV_BACKEND", "numpy" if backend == "numpy" else "auto")
    return backend
