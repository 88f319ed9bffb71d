"""hp-scp's stop test (``SettledProbe``): a small step or a settled objective first lightens a
trust weight that can still be lightened; a settling seen again after such a probe is
converged. Pure logic."""

from __future__ import annotations

from worker.solver.methods.hp_scp.stop import SettledProbe


def test_a_small_step_under_a_heavy_weight_is_probed_each_time() -> None:
    stop = SettledProbe()
    assert stop.judge(True, False, True, can_lighten=True) == (False, True)
    assert stop.judge(True, False, True, can_lighten=True) == (False, True)
    assert stop.judge(True, False, True, can_lighten=False) == (True, False)  # at the floor


def test_a_settled_objective_is_probed_once_then_converged() -> None:
    stop = SettledProbe()
    assert stop.judge(False, True, True, can_lighten=True) == (False, True)
    # the lighter steps were rejected; accepted again at a heavy weight, still settled
    assert stop.judge(False, True, True, can_lighten=True) == (True, False)
    assert stop.judge(True, True, True, can_lighten=True) == (True, False)


def test_a_new_mesh_starts_the_settling_again() -> None:
    stop = SettledProbe()
    stop.judge(False, True, True, can_lighten=True)
    stop.reset()
    assert stop.judge(False, True, True, can_lighten=True) == (False, True)


def test_unmet_defects_neither_converge_nor_probe() -> None:
    stop = SettledProbe()
    assert stop.judge(True, True, False, can_lighten=True) == (False, False)
    assert stop.judge(False, False, True, can_lighten=True) == (False, False)
    assert not stop.probed
