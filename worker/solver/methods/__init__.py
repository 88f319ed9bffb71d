"""Solution methods: one package per method on the shared SCP driver (``scp.loop``).

Each package ``worker/solver/methods/<name>/`` holds its support checks, its driver hooks and
its linearization, and exports ``METHOD`` (``base.MethodInfo``); ``registry`` finds them from
the one list of options models in ``app.schemas.methods``. ``selection`` is ``auto``'s rule
(which methods accept a document, in which order) and ``capabilities`` the matrix of features
each method takes, probed from the methods' own checks; ``catalog`` lists them all.
"""

from worker.solver.methods.catalog import list_methods
from worker.solver.methods.registry import METHODS
from worker.solver.methods.selection import check_support

__all__ = ["METHODS", "check_support", "list_methods"]
