"""The public API of the lab, for scripts and notebooks (docs/api.md). These names stay.

    from sim_bridge.api import load_experiment, run_campaign, summarise, simulate
    exp = load_experiment("ch5a")                          # or a path to your own experiment file
    camp = run_campaign(exp, runs=20, filters=["RJMRPF"], simulator=my_world)
    doc = summarise(camp)                                  # the results.json document

A simulator is any callable `(experiment, seed, nav) -> Trajectory` that flies the experiment's
world for `experiment.duration_s` at `experiment.dt_s`, calling `nav(t, y, mask, u_prev)` once per
frame with the world's sensor rows and the input applied since the previous frame, flying on the
returned estimate's `.state`, and returning the `Trajectory` (`simulate` is the built-in one).
"""

from __future__ import annotations

from sim_bridge.campaign import Campaign, run_campaign, simulate
from sim_bridge.report import summarise, write_report
from sim_bridge.scenario import Scenario, experiment_service_config
from sim_bridge.scenario import load_scenario as load_experiment
from sim_bridge.simulate import SimStepper, Trajectory, default_autopilot, run

__all__ = ["Campaign", "Scenario", "SimStepper", "Trajectory", "default_autopilot",
           "experiment_service_config", "load_experiment", "run", "run_campaign", "simulate", "summarise",
           "write_report"]
