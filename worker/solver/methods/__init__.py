"""Solution methods: one package per method on the shared SCP driver (``scp.loop``).

Each package ``worker/solver/methods/<name>/`` holds its support checks, its driver hooks and
its linearization, and exports ``METHOD`` (``base.MethodInfo``); ``registry`` finds them from
the one list of options models in ``app.schemas.methods``.
"""

from worker.solver.methods.registry import METHODS, check_support, list_methods

__all__ = ["METHODS", "check_support", "list_methods"]
