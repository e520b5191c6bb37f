"""Airframe model: derived discrete F, B against the thesis's printed matrices; trim; modes (SPEC 2)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from fdir_service.airframe import STATE_NAMES, derivatives, linearize, trim
from fdir_service.airframe.linearize import PRINTED_B, PRINTED_F, linear_model

INPUTS = ("delta_e", "delta_t")


@pytest.fixture(scope="module")
def model(params):
    return linearize(params, 40.0, 500.0, 0.05)


@pytest.mark.parametrize(
    "i,j", [(i, j) for i in range(5) for j in range(5)],
    ids=[f"F[{r},{c}]" for r in STATE_NAMES for c in STATE_NAMES])
def test_derived_F_matches_printed_entry(model, i, j):
    assert abs(model.F[i, j] - PRINTED_F[i, j]) <= 0.006, (model.F[i, j], PRINTED_F[i, j])


@pytest.mark.parametrize(
    "i,j", [(i, j) for i in range(5) for j in range(2)],
    ids=[f"B[{r},{c}]" for r in STATE_NAMES for c in INPUTS])
def test_derived_B_matches_printed_entry(model, i, j):
    assert abs(model.B[i, j] - PRINTED_B[i, j]) <= 0.006, (model.B[i, j], PRINTED_B[i, j])


def test_trim_values_match_spec(params):
    tr = trim(params, 40.0, 500.0)
    assert tr.z[0] == -500.0
    assert tr.z[1] == pytest.approx(39.954, abs=5e-4)
    assert tr.z[2] == pytest.approx(1.912, abs=5e-4)
    assert np.degrees(tr.z[3]) == pytest.approx(2.74, abs=5e-3)
    assert np.degrees(tr.alpha) == pytest.approx(np.degrees(tr.z[3]), abs=1e-12)
    assert np.degrees(tr.u[0]) == pytest.approx(-4.76, abs=5e-3)
    assert tr.u[1] == pytest.approx(0.532, abs=5e-4)
    assert tr.residual < 1e-9
    # Independent check of the residual: every derivative except p_d' (level flight: 0 too) vanishes.
    assert np.max(np.abs(derivatives(tr.z, tr.u, params))) < 1e-9


def test_continuous_modes_match_spec(model):
    ev = np.linalg.eigvals(model.A)
    osc = ev[np.abs(ev.imag) > 1e-6]
    short = osc[np.argmax(np.abs(osc.imag))]
    phug = osc[np.argmin(np.abs(osc.imag))]
    assert short.real == pytest.approx(-1.27, abs=0.01)
    assert abs(short.imag) == pytest.approx(5.69, abs=0.01)
    assert phug.real == pytest.approx(-0.21, abs=0.01)
    assert abs(phug.imag) == pytest.approx(0.26, abs=0.01)


def test_mass_is_a_parameter(params, model):
    light = dataclasses.replace(params, m=13.5)
    lm = linearize(light, 40.0, 500.0, 0.05)
    # The thrust column scales with 1/m: B[u, delta_t] grows by ~25/13.5.
    assert lm.B[1, 1] / model.B[1, 1] == pytest.approx(25.0 / 13.5, rel=0.02)
    off = np.sum(np.abs(lm.F - PRINTED_F) > 0.006) + np.sum(np.abs(lm.B - PRINTED_B) > 0.006)
    assert off >= 5
    assert lm.trim.u[1] != pytest.approx(model.trim.u[1], abs=1e-3)


def test_printed_and_derived_are_selectable(params):
    pm = linear_model(params, "printed")
    dm = linear_model(params, "derived")
    assert pm.source == "printed" and np.array_equal(pm.F, PRINTED_F)
    assert dm.source == "derived" and not np.array_equal(dm.F, PRINTED_F)
    # Absolute-coordinate step: the trim is an equilibrium of both.
    for mdl in (pm, dm):
        assert np.allclose(mdl.step(mdl.trim.z, mdl.trim.u), mdl.trim.z, atol=1e-12)
    with pytest.raises(ValueError):
        linear_model(params, "printed", dt=0.02)
