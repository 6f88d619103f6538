"""The sim suite runs once, on the compiled step.

Every scene the ``Scene`` accepts has kernels, so ``RIGID_ENV_BACKEND=auto`` (set for every test
here) steps every scene a test builds compiled. The numpy step is still there
(``backend="numpy"``) until the engine issue deletes it: the tests that compare the two pass
``backend=`` themselves (``test_compiled*.py``). The modules in ``BOTH`` test the two
implementations of the contact solver's parts directly, each through the ``sim_backend``
fixture (``[numpy]`` and ``[compiled]``): cheap solves of fixed problems, no scene compiles.
"""

import pytest

BACKENDS = ("numpy", "compiled")
BOTH = {"test_contact_newton.py": "tests numpy's and the kernels' solver parts on one problem"}


def pytest_generate_tests(metafunc):
    if "sim_backend" in metafunc.fixturenames:
        both = metafunc.definition.path.name in BOTH
        metafunc.parametrize("sim_backend", BACKENDS if both else ("compiled",), indirect=True)


@pytest.fixture
def sim_backend(request):
    return request.param


@pytest.fixture(autouse=True)
def auto_backend(monkeypatch):
    monkeypatch.setenv("RIGID_ENV_BACKEND", "auto")
