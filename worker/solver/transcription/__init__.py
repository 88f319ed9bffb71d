"""Transcriptions: how a continuous entry problem becomes one finite conic subproblem."""
