"""The package's version, on the ground floor: archives, FMUs and reports stamp it, and
importing it from the package's face would import everything above them."""

__version__ = "0.2.0"  # keep equal to pyproject.toml's [project] version (a test checks)
