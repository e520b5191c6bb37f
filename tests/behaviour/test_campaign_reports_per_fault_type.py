"""A campaign whose world injects a typed fault (a stuck barometer, issue 17) is scored by item and
type and its report shows the per-type table and confusion table."""

import dataclasses
import json

from sim_bridge.campaign import run_campaign
from sim_bridge.report import write_report
from tests.behaviour.test_campaign_runs_seeds_and_reports import fake_builder


def test_a_stuck_barometer_is_reported_per_type_by_item_and_type(ch4, tmp_path):
    gnss, baro = ch4.faults                                    # gnss bias 10-30 s, baro 20-40 s
    world = (gnss, dataclasses.replace(baro, fault_type="stuck"))
    sc = dataclasses.replace(ch4, faults=world)
    camp = run_campaign(sc, 2, seed=3, workers=1, progress=False, builder=fake_builder,
                        filters=("JMRPF",))
    doc = write_report(camp, tmp_path, make_figures=False)
    y = doc["filters"]["JMRPF"]["yardstick"]
    # the strict yardstick counts by item, as the service declares: the baro item was declared ...
    assert y["isolation"] == {"gnss": {"gnss": 2}, "baro": {"baro": 2}} and y["isolation_accuracy"] == 1.0
    # ... but the ch4 estimator has bias entries only: the stuck baro was declared as the wrong type
    bt = y["by_type"]
    assert bt["confusion"] == {"gnss_alt:bias": {"gnss_alt:bias": 2}, "baro_alt:stuck": {"baro_alt:bias": 2}}
    st = bt["types"]["stuck"]
    assert st["episodes"] == 2 and st["detection_fraction"] == 1.0 and st["right_fraction"] == 0.0
    assert st["right_item_fraction"] == 1.0 and st["magnitude_rmse"] == {}     # no stuck entry
    assert bt["types"]["bias"]["magnitude_rmse"]["m"] < 2.0
    md = (tmp_path / "report.md").read_text()
    assert "## Per fault type" in md and "| baro_alt:stuck | 2 | 0 |" in md
    assert json.loads((tmp_path / "results.json").read_text())["filters"]["JMRPF"]["yardstick"]["by_type"]
