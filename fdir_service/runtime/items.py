"""Monitored items: the targets the service reports on, each watched by one or more typed entries.

An estimator's `[[faults]]` entries (nf of them, config order) each watch a `target` (a measurement
row or an actuator) with a `type` ("bias", "stuck", "noisy", "drift", "blocked" for sensors;
"bias", "jammed", "effectiveness", "engine" for actuators). A monitored *item* is a target with its
entries; it is named by the id of its first entry. Item order = order of first appearance in the
config, so an estimator whose entries all watch different targets has items = entries, in the same
order.

Per frame an item has P(item faulty), its most probable type (the entry with the highest mode-1
probability; the first one on a tie) and that entry's user-facing value (SI, or unitless for a
noisy multiplier k, an effectiveness gain g and an engine's thrust share). `combine_probability`
documents the combination.

Pure functions; shapes: nf entries, ni items (ni <= nf).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from fdir_service.estimation.base import StepOutput
from fdir_service.estimator_config import FaultSpec
from fdir_service.mavlink import dialect

TYPE_CODES: dict[str, int] = {
    "bias": dialect.FDIR_FAULT_TYPE_BIAS,
    "stuck": dialect.FDIR_FAULT_TYPE_STUCK,
    "noisy": dialect.FDIR_FAULT_TYPE_NOISY,
    "jammed": dialect.FDIR_FAULT_TYPE_JAMMED,
    "effectiveness": dialect.FDIR_FAULT_TYPE_EFFECTIVENESS,
    "blocked": dialect.FDIR_FAULT_TYPE_BLOCKED,
    "drift": dialect.FDIR_FAULT_TYPE_DRIFT,
    "engine": dialect.FDIR_FAULT_TYPE_ENGINE,
}
"""Fault type name -> FDIR_FAULT_TYPE code (FDIR_ESTIMATE.fault_type, the recording's `ft_<id>`)."""
TYPE_NAMES: dict[int, str] = {v: k for k, v in TYPE_CODES.items()}
"""FDIR_FAULT_TYPE code -> fault type name."""


@dataclass(frozen=True)
class ItemLayout:
    """How entries group into items. names (ni,): item names (id of each item's first entry);
    targets (ni,): the watched row or actuator; entries (ni,): entry indices (into the config's
    faults, ascending) of each item."""

    names: tuple[str, ...]
    targets: tuple[str, ...]
    entries: tuple[tuple[int, ...], ...]

    def __len__(self) -> int:
        return len(self.names)


@dataclass(frozen=True)
class ItemFrame:
    """One frame's item view (ni items, `ItemLayout` order). p (ni,): P(item faulty); entry (ni,):
    index of the most probable entry; types (ni,): its type; value (ni,): its user-facing value
    (SI; k and g unitless); share (ni,): that entry's P over P(item), in [0, 1] (`type_share`; 1
    for a one-entry item)."""

    p: np.ndarray
    entry: np.ndarray
    types: tuple[str, ...]
    value: np.ndarray
    share: np.ndarray


@dataclass(frozen=True)
class ItemReport:
    """What the pipeline hands observers per frame (`PipelineObserver.on_items`) when the estimator
    is not `is_plain`: item names (ni,), the frame's `ItemFrame`, declared (ni,) after hysteresis."""

    names: tuple[str, ...]
    view: ItemFrame
    declared: tuple[bool, ...]

    @property
    def type_codes(self) -> list[int]:
        """FDIR_FAULT_TYPE code (ni,) of each item's most probable type."""
        return [type_code(t) for t in self.view.types]


def item_layout(faults: Sequence[FaultSpec]) -> ItemLayout:
    """Group the entries (nf,) by target, items in order of each target's first entry."""
    groups: dict[str, list[int]] = {}
    for j, f in enumerate(faults):
        groups.setdefault(f.target, []).append(j)
    entries = tuple(tuple(g) for g in groups.values())
    return ItemLayout(tuple(faults[g[0]].id for g in entries), tuple(groups), entries)


def entry_types(faults: Sequence[FaultSpec], out: StepOutput | None = None) -> tuple[str, ...]:
    """Each entry's type (nf,): the step's `fault_types` when the filter reports them, else the
    estimator config's `type` ("bias" for a fault without one, e.g. a lab scenario's channel)."""
    if out is not None and out.fault_types:
        return tuple(out.fault_types)
    return tuple(getattr(f, "fault_type", "bias") for f in faults)


def is_plain(layout: ItemLayout, types: Sequence[str]) -> bool:
    """True when every item has one entry and every entry is a bias: the service's output is then
    exactly what it was before fault types (no type fields published or recorded)."""
    return all(len(e) == 1 for e in layout.entries) and all(t == "bias" for t in types)


def combine_probability(p: np.ndarray, noisy: np.ndarray | None = None) -> np.ndarray | float:
    """P(item faulty) from its entries' mode-1 probabilities p (..., k), unitless in [0, 1]; noisy
    (k,) bool marks noisy entries (None: none).

    The additive types of an item (bias, stuck, jammed, effectiveness) are exclusive in every
    particle (one of them in mode 1 at a time, `fault_types.ItemExclusion`), so P(one of them) is
    their sum, exactly; a noisy entry may stand beside one of them and is combined as an independent
    event, 1 - (1 - P(additive)) prod(1 - p_noisy). When a fault's type is ambiguous the types share
    the evidence (stuck 0.6, bias 0.3) and the item still has the whole of it (0.9). A single
    entry's p is returned unchanged (bit for bit), so a one-entry item behaves exactly as its entry.
    """
    p = np.asarray(p, dtype=float)
    if p.shape[-1] == 1:
        return float(p[0]) if p.ndim == 1 else p[..., 0].copy()
    noisy = np.zeros(p.shape[-1], bool) if noisy is None else np.asarray(noisy, bool)
    additive = np.minimum(p[..., ~noisy].sum(axis=-1), 1.0)
    out = 1.0 - (1.0 - additive) * np.prod(1.0 - p[..., noisy], axis=-1)
    return float(out) if out.ndim == 0 else out


def item_probability(prob: np.ndarray, layout: ItemLayout, types: Sequence[str]) -> np.ndarray:
    """P(item faulty) (..., ni) from the entries' P(fault) prob (..., nf) (`combine_probability`)."""
    prob = np.asarray(prob, dtype=float)
    out = np.empty(prob.shape[:-1] + (len(layout),))
    for i, idx in enumerate(layout.entries):
        out[..., i] = combine_probability(prob[..., list(idx)], np.array([types[j] == "noisy" for j in idx]))
    return out


def item_frame(layout: ItemLayout, out: StepOutput, types: Sequence[str]) -> ItemFrame:
    """The item view of one step: P(item faulty) (ni,), its most probable entry (ni,), that
    entry's type and user-facing value (`StepOutput.value_of`)."""
    prob = np.asarray(out.fault_probability, dtype=float)
    if len(layout) == len(types):   # one entry per item: the entries themselves
        v = out.fault_value if out.fault_value is not None else out.fault_estimate
        return ItemFrame(prob[:len(types)].copy(), np.arange(len(types)), tuple(types),
                         np.asarray(v, dtype=float)[:len(types)].copy(), np.ones(len(types)))
    p = np.empty(len(layout))
    best = np.empty(len(layout), dtype=int)
    for i, idx in enumerate(layout.entries):
        pe = prob[list(idx)]
        p[i] = combine_probability(pe, np.array([types[j] == "noisy" for j in idx]))
        best[i] = idx[int(np.argmax(np.where(np.isnan(pe), -np.inf, pe)))]
    value = np.array([out.value_of(int(j)) for j in best])
    return ItemFrame(p, best, tuple(types[int(j)] for j in best), value, type_share(prob[best], p))


def type_share(p_entry: np.ndarray, p_item: np.ndarray) -> np.ndarray:
    """The most probable entry's share of its item's P (...,): p_entry / p_item clipped to [0, 1];
    0 where P(item) is 0 or not finite (no type to name)."""
    p_entry, p_item = np.asarray(p_entry, dtype=float), np.asarray(p_item, dtype=float)
    ok = np.isfinite(p_item) & (p_item > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(ok, np.clip(np.nan_to_num(p_entry / np.where(ok, p_item, 1.0)), 0.0, 1.0), 0.0)


def type_code(name: str) -> int:
    """The FDIR_FAULT_TYPE code of a fault type name ("stuck" -> 1)."""
    return TYPE_CODES[name]
