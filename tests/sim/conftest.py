"""The sim tests step the compiled kernels, the simulator's one implementation: every test runs
with ``RIGID_ENV_BACKEND`` unset, so a scene it builds takes the default ``"compiled"`` unless
it passes ``backend=`` itself."""

import pytest


@pytest.fixture(autouse=True)
def default_backend(monkeypatch):
    monkeypatch.delenv("RIGID_ENV_BACKEND", raising=False)
