"""Solver core: entry trajectory optimization by sequential convex programming.

Imports neither FastAPI nor Celery, so it runs as a plain library and from the
``trajopt`` command line as well as inside the service's workers.
"""
