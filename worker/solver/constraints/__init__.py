"""Linearized path and no-fly-zone constraints of the time-domain SCP (paper 002 sec. 3.3)."""
