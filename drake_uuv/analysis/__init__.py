"""Analysis of logged runs: figures and tables."""
