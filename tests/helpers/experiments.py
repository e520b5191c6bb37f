"""Shared test helpers: the service with the thesis ch4 experiment's estimator (the lab hands it in)."""

from __future__ import annotations

from fdir_service.service_config import ServiceConfig, default_config_path
from sim_bridge.scenario import experiment_service_config, load_scenario

CH4 = load_scenario("ch4")
"""The ch4 experiment: its world flies the tests' flights, its estimator monitors them."""
BASE_TEXT = default_config_path().read_text()


def ch4_service(text: str | None = None) -> ServiceConfig:
    """The default service config (or `text`) monitoring with the ch4 experiment's estimator."""
    return experiment_service_config(CH4, text)


def with_parts(scenario, **settings):
    """The experiment with its estimator's part settings (`[parts]`) changed."""
    import dataclasses

    est = scenario.estimator
    return dataclasses.replace(scenario, estimator=dataclasses.replace(
        est, settings=dataclasses.replace(est.settings, **settings)))
