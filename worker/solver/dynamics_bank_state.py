"""Former home of the bank-state model: re-exports ``worker.solver.models.bank_state``.

Kept until its importers move; ``NZ`` is ``models.layout.BANK_STATE.size``.
"""

from __future__ import annotations

from worker.solver.models.bank_state import SIGMA, BankStateDerivatives, bank_state_dynamics
from worker.solver.models.layout import BANK_STATE

NZ = BANK_STATE.size

__all__ = ["NZ", "SIGMA", "BankStateDerivatives", "bank_state_dynamics"]
