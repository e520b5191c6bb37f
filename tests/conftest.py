"""Shared fixtures of the test suite. Tests live by kind: `unit/` (one part, no simulator flight),
`behaviour/` (a filter, the pipeline, a campaign or a log doing what it should on real data),
`e2e/` (real processes and sockets). Shared helpers that are not fixtures: `tests/helpers/`."""

from __future__ import annotations

import pytest
from threadpoolctl import threadpool_limits

from fdir_service.airframe import load_airframe
from fdir_service.estimator_config import load_estimator

# One BLAS thread, as every `fdir` / `sim-bridge` command (`cliutil.run`) and campaign worker: the
# tests fly the service's floating-point path, and `make test`'s two pytest-xdist workers do not
# oversubscribe CI's two cores (two threads each ran no faster than one worker)
threadpool_limits(limits=1, user_api="blas")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark every test with its kind (its folder): `pytest -m unit`, `-m "not e2e"` ..."""
    for item in items:
        kind = item.path.parent.name
        if kind in ("unit", "behaviour", "e2e"):
            item.add_marker(getattr(pytest.mark, kind))


@pytest.fixture(scope="session")
def ch4():
    """The ch4 experiment (thesis section 4.5): its world flies, its estimator monitors."""
    from tests.helpers.experiments import CH4

    return CH4


@pytest.fixture(scope="session")
def default_estimator():
    """config/estimators/aerosonde.toml: what `fdir run` monitors with no arguments."""
    return load_estimator()


@pytest.fixture(scope="session")
def params():
    """The Aerosonde airframe parameters (config/airframes/aerosonde.toml)."""
    return load_airframe()
