"""When an engine quits or the elevator binds, the fault's own type takes it (engine loss, jam),
and the input's offset entry stays in mode 0, where its drift follows the particles that do not
yet hold the fault: in the 1-2 s before the fault's hypothesis wins, they absorb part of it. The
fault-free value that exits return to (`jump.DriftMemory`) learnt that offset, and once the fault
ended every exit mispredicted by it: the input stood declared for tens of seconds. With
parts.fault_free_memory = "input_item" an input's fault-free value is kept from the particles
whose whole input is fault-free, and with fault_free_rollback_s = 2 it freezes at its value from
2 s before the fault's hypothesis won (`jump.MemoryRollback`; the catalogue's default since stop
52, with every entry kept by item since stop 53: both flights clear with either; docs/faults.md,
"The fault-free value from before the onset", "Every entry by item").

Campaign seed 0, the monitor loop, flown to a few seconds past the yardstick's grace:
real-engine run 44 (the engine lost 22.0-34.0 s), real-actuators run 1 (the elevator bound
17.2-20.5 s)."""

from __future__ import annotations

from tests.helpers.declarations import MEMORY_BEFORE_STOP_52 as BEFORE_STOP_52
from tests.helpers.declarations import declared_when_quiet


def test_an_engine_that_comes_back_leaves_the_throttle_clear():
    assert declared_when_quiet("real-engine", 44, 50.0) == {}


def test_with_the_memory_learnt_during_the_fault_the_throttle_stands():
    standing = declared_when_quiet("real-engine", 44, 50.0, **BEFORE_STOP_52)
    assert standing.get("dt", 0.0) > 10.0                 # of the 13 s from 37 to 50 s


def test_a_freed_jam_leaves_the_elevator_clear():
    assert declared_when_quiet("real-actuators", 1, 40.0) == {}


def test_with_the_memory_learnt_during_the_jam_the_elevator_stands():
    standing = declared_when_quiet("real-actuators", 1, 40.0, **BEFORE_STOP_52)
    assert standing.get("de", 0.0) > 10.0                 # of the 16.5 s from 23.5 to 40 s
