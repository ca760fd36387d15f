"""Attitude generators: the paper's Algorithms 1 and 2 and an information-seeking planner."""
