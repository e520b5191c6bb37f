"""`fdir bench --parts` (`commands.bench_parts`): a step split by slot, and the filter left as it was."""

from __future__ import annotations

import numpy as np

from fdir_service.commands.bench import estimator_source
from fdir_service.commands.bench_parts import print_parts, time_parts


def test_a_step_splits_into_its_slots_and_the_filter_is_left_as_it_was(capsys):
    setups = estimator_source(None)(("RJMRPF", "bootstrap"), 200, 60, 20)
    rows = {name: time_parts(f, frames, 60, 20) for name, (f, frames) in setups.items()}
    for name, r in rows.items():
        parts = r["predict"] + r["jump"] + r["sentinels"] + r["correction"] + r["resample"]
        assert 0.0 < parts <= r["step"], name
        f = setups[name][0]
        assert "step" not in vars(f) and "_resample" not in vars(f)
        assert "predict" not in vars(f.parts.predict) and "update" not in vars(f.parts.correction)
    assert rows["bootstrap"]["resample_share"] == 1.0          # resamples every step
    assert 0.0 < rows["RJMRPF"]["resample_share"] < 1.0        # below N_eff's threshold only
    assert rows["RJMRPF"]["jump"] > 10 * rows["bootstrap"]["jump"]   # NoJump does nothing
    # the filter steps on after the timing, bit for bit as an untimed twin of it
    twin, frames = estimator_source(None)(("RJMRPF",), 200, 60, 20)["RJMRPF"]
    for k in range(80):
        twin.step(frames.t[k], frames.y[k], frames.mask[k], frames.u[k])
    f = setups["RJMRPF"][0]
    assert np.array_equal(f.X, twin.X) and np.array_equal(f.w, twin.w)
    print_parts(rows, "title")
    out = capsys.readouterr().out
    assert "RJMRPF" in out and "resampling steps" in out and "us each" in out
