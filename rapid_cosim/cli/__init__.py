"""The command line: ``main`` (``rapid-cosim``: its ``parser`` and ``commands``, thin over the
Python API) and ``campaign`` (the staged-test campaign as the make targets run it)."""

from .main import main

__all__ = ["main"]
