"""Developer tools of the repository (not installed with rigd): ``python -m tools.figures``."""
