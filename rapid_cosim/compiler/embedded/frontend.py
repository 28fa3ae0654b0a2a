"""Modelica text -> pymoca flat class, with every failure located in the user's files."""

from __future__ import annotations

import copy

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
    flat_class = list(flat.classes.values())[0]
    _restore_declarations(flat_class, copy.deepcopy(tree), class_name)
    return flat_class


def _restore_declarations(flat_class, tree, class_name: str) -> None:
    """What pymoca 0.12 drops from a declaration whose type is a derived one
    (``output Types.PerUnit pm "power"``): its description, and at the top level its
    causality. Both are read back from the instance tree (instantiation writes into the
    tree it is given, hence the copy)."""
    comments: dict[str, str] = {}
    causality: dict[str, str] = {}

    def walk(instance, prefix: str, depth: int) -> None:
        if depth > 20:  # a package's nesting, never a cycle
            return
        for name, sym in instance.symbols.items():
            full = f"{prefix}.{name}" if prefix else name
            if sym.comment:
                comments.setdefault(full, sym.comment)
            if not prefix:
                causality.update({full: p for p in sym.prefixes if p in ("input", "output")})
            if isinstance(sym.type, pymoca.tree.InstanceClass) and sym.type.type != "type":
                walk(sym.type, full, depth + 1)
        for extends in getattr(instance, "extends", []):
            if isinstance(extends, pymoca.tree.InstanceClass):
                walk(extends, prefix, depth + 1)

    walk(pymoca.tree.instantiate(tree, class_name), "", 0)
    for name, s in flat_class.symbols.items():
        if not s.comment:
            s.comment = comments.get(name, "")
        if name in causality and causality[name] not in s.prefixes:
            s.prefixes.insert(0, causality[name])


def translate(source: PackageSource, class_name: str, tree=None) -> ExplicitModel:
    """The explicit ODE of one model of the package."""
    flat = flatten(source, class_name, tree)

    def locate(fname: str):
        line = find_call(source, class_name, fname)
        return source.locate(line) if line else None

    symbolic = Translator(flat, class_name, locate).run()
    return solve_model(symbolic)
