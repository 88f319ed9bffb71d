"""State models: layouts of the states each formulation carries, and their dynamics."""
