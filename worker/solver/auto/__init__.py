"""``auto``: the methods that accept a problem, tried in the documented order within one time
budget (``runner``), and the result document that reports every attempt (``document``,
``outcome``). The rule itself is ``worker.solver.methods.selection``."""

from worker.solver.auto.runner import solve_auto

__all__ = ["solve_auto"]
