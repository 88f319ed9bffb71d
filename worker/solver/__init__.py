"""Solver core: entry trajectory optimization by sequential convex programming.

Imports neither FastAPI nor Celery, so it runs as a plain library and from the
``trajopt`` command line as well as inside the service's workers.
"""

FIRST_COMPILE = "about a minute on a 2-core machine"
"""How long the first compilation of the solver's kernels takes after an install (measured with
``python -m worker.solver.warmup`` on an empty numba cache: 40-89 s, 21-23 s of CPU time;
docs/service.md, "First compilation", has the runs)."""
