"""Modelica text -> pymoca flat class, with every failure located in the user's files."""

from __future__ import annotations

import pymoca.ast
import pymoca.parser
import pymoca.tree

from ...errors import ModelicaError, ModelicaSyntaxError
from ..modelica_source import PackageSource, check_supported, find_call
from .structure import ExplicitModel, solve_model
from .symbolic import Translator


def parse(source: PackageSource):
    try:
        return pymoca.parser.parse(source.text)
    except pymoca.parser.ModelicaSyntaxError as e:
        message = e.args[0] if e.args else str(e)
        info = e.args[1] if len(e.args) > 1 else None
        line = info[1] if isinstance(info, tuple) and len(info) > 1 else 1
        raise source.error(f"syntax error: {message}", line, ModelicaSyntaxError) from None


def flatten(source: PackageSource, class_name: str, tree=None):
    tree = tree if tree is not None else parse(source)
    check_supported(source, class_name)
    try:
        flat = pymoca.tree.flatten(tree, pymoca.ast.ComponentRef.from_string(class_name))
    except Exception as e:  # pymoca raises bare Exceptions for lookup failures
        raise ModelicaError(f"pymoca could not flatten {class_name}: {e}") from e
    return list(flat.classes.values())[0]


def translate(source: PackageSource, class_name: str, tree=None) -> ExplicitModel:
    """The explicit ODE of one model of the package."""
    flat = flatten(source, class_name, tree)

    def locate(fname: str):
        line = find_call(source, class_name, fname)
        return source.locate(line) if line else None

    symbolic = Translator(flat, class_name, locate).run()
    return solve_model(symbolic)
