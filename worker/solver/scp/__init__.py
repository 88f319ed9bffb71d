"""SCP strategies: the outer loops that linearize, solve a conic subproblem, and update."""
