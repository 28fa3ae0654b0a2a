"""pymoca's flattened model -> CasADi SX symbols and residual equations.

We translate pymoca's AST ourselves instead of using its CasADi backend: that backend
needs patches for casadi 3.8 (``MX.__div__``), builds MX (structural analysis wants SX),
rejects dotted function names and drops what it does not know without a word. Walking
the flat AST lets every unknown construct become an error that names it.

Semantics chosen where Modelica leaves the tool a choice:
- Relations between ``time`` and a parameter expression become *conditions*: discrete
  values that change only at exact time events (the FMU reports them through
  ``nextEventTime``). An integrator stepping past a source step thus never sees it early.
- Every other relation is evaluated as with ``noEvent`` (no state events): the iGrGen
  models write switching with smooth functions instead.
- ``noEvent(x)``, ``smooth(n, x)`` and ``homotopy(actual, simplified)`` are ``x`` and
  ``actual``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import pymoca.ast as A

from ...errors import ModelicaError, UnsupportedConstruct

_UNARY = {
    "abs": ca.fabs, "sign": ca.sign, "sqrt": ca.sqrt, "exp": ca.exp, "log": ca.log,
    "log10": ca.log10, "sin": ca.sin, "cos": ca.cos, "tan": ca.tan, "asin": ca.asin,
    "acos": ca.acos, "atan": ca.atan, "sinh": ca.sinh, "cosh": ca.cosh, "tanh": ca.tanh,
    "floor": ca.floor, "ceil": ca.ceil,
}
_BINARY = {"min": ca.fmin, "max": ca.fmax, "atan2": ca.atan2}
_RELATIONS = {"<", "<=", ">", ">=", "==", "<>"}


@dataclass
class Variable:
    name: str
    sym: ca.SX
    description: str = ""
    unit: str = ""
    start: float | None = None
    min: float | None = None
    max: float | None = None
    fixed: bool = False
    is_output: bool = False
    kind: str = "Real"  # "Integer" or "Boolean" for a flag parameter (held as a Real inside)


@dataclass
class Condition:
    """``time >= event_time`` held constant between events."""

    sym: ca.SX
    event_time: ca.SX  # a function of the parameters only
    text: str


@dataclass
class SymbolicModel:
    """Residual form ``0 = r(der(x), x, w, u, p, c, t)`` of one flattened model."""

    name: str
    time: ca.SX
    parameters: list[Variable]  # independent, tunable
    calculated: list[tuple[Variable, ca.SX]]  # bound to expressions of the parameters
    states: list[Variable]
    derivatives: list[ca.SX]
    algebraics: list[Variable]
    inputs: list[Variable]
    conditions: list[Condition]
    equations: list[ca.SX]
    initial_equations: list[ca.SX]
    equation_text: list[str] = field(default_factory=list)


class Translator:
    """Builds a :class:`SymbolicModel` from one pymoca flat class."""

    def __init__(self, flat_class, name: str, locate_call=None):
        self.cls = flat_class
        self.name = name
        # Maps an unknown function name to a (file, line) error; given by the frontend.
        self._locate_call = locate_call or (lambda fname: None)
        self.t = ca.SX.sym("time")
        self.syms: dict[str, ca.SX] = {"time": self.t}
        self.der_syms: dict[str, ca.SX] = {}
        self.conditions: list[Condition] = []
        self._dynamic: list[ca.SX] = [self.t]

    # -- declarations -------------------------------------------------------------------
    def run(self) -> SymbolicModel:
        params, calc_src, states, algebraics, inputs = [], [], [], [], []
        for s in self.cls.symbols.values():
            kind = self._check_symbol(s)
            var = Variable(
                name=s.name,
                sym=ca.SX.sym(s.name),
                description=s.comment or "",
                unit=_literal_str(s.unit),
                start=_literal_float(s.start),
                min=_literal_float(s.min),
                max=_literal_float(s.max),
                fixed=bool(_literal(s.fixed)),
                is_output="output" in s.prefixes and "." not in s.name,
                kind=kind,
            )
            self.syms[s.name] = var.sym
            if "parameter" in s.prefixes or "constant" in s.prefixes:
                value = s.value
                if isinstance(value, A.Primary) and value.value is None:
                    raise ModelicaError(f"parameter {s.name} of {self.name} has no value")
                if isinstance(value, A.Primary):
                    var.start = float(value.value)
                    if kind != "Real" and var.start != round(var.start):
                        raise ModelicaError(f"{kind} parameter {s.name} of {self.name} = {value.value!r} is not "
                                            "a whole number")
                    params.append(var)
                else:
                    calc_src.append((var, value))
            elif "state" in s.prefixes:
                states.append(var)
                self.der_syms[s.name] = ca.SX.sym(f"der({s.name})")
            elif "input" in s.prefixes and "." not in s.name:
                var.start = 0.0 if var.start is None else var.start
                inputs.append(var)
            else:
                algebraics.append(var)
        self._dynamic += [v.sym for v in states + algebraics + inputs]

        calculated = []
        for var, expr in calc_src:
            value = self.expr(expr)
            if _is_constant(value):
                var.start = float(ca.evalf(value))
                params.append(var)
            elif var.kind != "Real":
                raise UnsupportedConstruct(f"{var.kind} parameter {var.name} of {self.name} is bound to other "
                                           "parameters; the embedded compiler takes flags with a constant value")
            else:
                calculated.append((var, value))
        calculated = _resolve_calculated(calculated, self.name)

        equations, texts = [], []
        for eq in self.cls.equations:
            equations.append(self._equation(eq))
            texts.append(_describe(eq))
        initial = [self._equation(eq) for eq in self.cls.initial_equations]

        model = SymbolicModel(
            name=self.name, time=self.t, parameters=params, calculated=calculated,
            states=states, derivatives=[self.der_syms[v.name] for v in states],
            algebraics=algebraics, inputs=inputs, conditions=self.conditions,
            equations=equations, initial_equations=initial, equation_text=texts,
        )
        return _substitute_calculated(model)

    def _check_symbol(self, s) -> str:
        """The variable's type: Real, or Integer and Boolean for parameters (flags such as
        GGOV1's Rselect, which the language lets no Real be compared with ``==``)."""
        type_name = getattr(s.type, "name", str(s.type))
        flag = type_name in ("Integer", "Boolean") and ("parameter" in s.prefixes or "constant" in s.prefixes)
        if type_name != "Real" and not flag:
            raise UnsupportedConstruct(
                f"variable {s.name} of type {type_name}: the embedded compiler handles Real variables, and "
                "Integer and Boolean parameters")
        dims = [d for d in s.dimensions for d in (d if isinstance(d, list) else [d])]
        if any(not (isinstance(d, A.Primary) and d.value in (1, None)) for d in dims):
            raise UnsupportedConstruct(f"array variable {s.name}: the embedded compiler handles scalars only")
        return type_name

    # -- equations and expressions -------------------------------------------------------
    def _equation(self, eq) -> ca.SX:
        if not isinstance(eq, A.Equation):
            kind = type(eq).__name__
            raise UnsupportedConstruct(f"{kind} in {self.name} is not supported by the embedded compiler")
        return self.expr(eq.left) - self.expr(eq.right)

    def expr(self, e) -> ca.SX:
        if isinstance(e, A.Primary):
            if isinstance(e.value, bool):
                return ca.SX(float(e.value))
            if isinstance(e.value, (int, float)):
                return ca.SX(float(e.value))
            raise UnsupportedConstruct(f"literal {e.value!r} in {self.name}")
        if isinstance(e, A.ComponentRef):
            return self._ref(e)
        if isinstance(e, A.IfExpression):
            result = self.expr(e.expressions[-1])
            for cond, value in zip(reversed(e.conditions), reversed(e.expressions[:-1])):
                result = ca.if_else(self.expr(cond), self.expr(value), result)
            return result
        if isinstance(e, A.Expression):
            return self._operation(e)
        raise UnsupportedConstruct(f"{type(e).__name__} in {self.name} is not supported by the embedded compiler")

    def _ref(self, e: A.ComponentRef) -> ca.SX:
        name = _cref_name(e)
        if name not in self.syms:
            raise ModelicaError(f"unknown name {name} in {self.name}")
        return self.syms[name]

    def _operation(self, e: A.Expression) -> ca.SX:
        op = e.operator
        if isinstance(op, A.ComponentRef):
            return self._call(_cref_name(op), e.operands)
        args = e.operands
        if op == "der":
            ref = args[0]
            name = _cref_name(ref) if isinstance(ref, A.ComponentRef) else None
            if name not in self.der_syms:
                raise UnsupportedConstruct(f"der() of {name or 'an expression'} in {self.name}: only der(state) is supported")
            return self.der_syms[name]
        if op in _RELATIONS:
            return self._relation(op, args[0], args[1])
        x = [self.expr(a) for a in args]
        if op == "+":
            return x[0] if len(x) == 1 else x[0] + x[1]
        if op == "-":
            return -x[0] if len(x) == 1 else x[0] - x[1]
        if op == "*":
            return x[0] * x[1]
        if op == "/":
            return x[0] / x[1]
        if op == "^":
            return x[0] ** x[1]
        if op == "and":
            return ca.logic_and(x[0], x[1])
        if op == "or":
            return ca.logic_or(x[0], x[1])
        if op == "not":
            return ca.logic_not(x[0])
        raise UnsupportedConstruct(f"operator {op!r} in {self.name} is not supported by the embedded compiler")

    def _call(self, fname: str, args) -> ca.SX:
        if fname in ("noEvent",):
            return self.expr(args[0])
        if fname == "smooth":
            return self.expr(args[1])
        if fname == "homotopy":
            return self.expr(args[0])
        if fname in _UNARY and len(args) == 1:
            return _UNARY[fname](self.expr(args[0]))
        if fname in _BINARY and len(args) == 2:
            return _BINARY[fname](self.expr(args[0]), self.expr(args[1]))
        located = self._locate_call(fname)
        message = (f"function {fname}() in {self.name} is not supported by the embedded compiler "
                   f"(built-ins it knows: {', '.join(sorted({*_UNARY, *_BINARY, 'noEvent', 'smooth', 'homotopy'}))})")
        if located:
            file, line = located
            raise UnsupportedConstruct(message, file=file, line=line)
        raise UnsupportedConstruct(message)

    def _relation(self, op: str, left, right) -> ca.SX:
        lhs, rhs = self.expr(left), self.expr(right)
        if _is_time(left) and not self._is_dynamic(rhs):
            return self._time_condition(rhs, after=op in (">", ">="), text=f"time {op} ...")
        if _is_time(right) and not self._is_dynamic(lhs):
            return self._time_condition(lhs, after=op in ("<", "<="), text=f"... {op} time")
        return {"<": lhs < rhs, "<=": lhs <= rhs, ">": lhs > rhs, ">=": lhs >= rhs,
                "==": lhs == rhs, "<>": lhs != rhs}[op]

    def _time_condition(self, event_time: ca.SX, after: bool, text: str) -> ca.SX:
        for cond in self.conditions:
            if ca.is_equal(cond.event_time, event_time, 20):
                break
        else:
            cond = Condition(ca.SX.sym(f"c{len(self.conditions)}"), event_time, text)
            self.conditions.append(cond)
        return cond.sym if after else 1 - cond.sym

    def _is_dynamic(self, e: ca.SX) -> bool:
        return bool(ca.depends_on(e, ca.vertcat(*self._dynamic, *self.der_syms.values())))


def _cref_name(e: A.ComponentRef) -> str:
    if any(i is not None for idx in e.indices for i in (idx if isinstance(idx, list) else [idx])):
        raise UnsupportedConstruct(f"subscripted reference {e.name}[...]: arrays are not supported by the embedded compiler")
    name = e.name
    for child in e.child:
        name += "." + _cref_name(child)
    return name


def _is_time(e) -> bool:
    return isinstance(e, A.ComponentRef) and _cref_name(e) == "time"


def _literal(value):
    return value.value if isinstance(value, A.Primary) else None


def _literal_float(value) -> float | None:
    v = _literal(value)
    if isinstance(value, A.Expression) and value.operator == "-" and len(value.operands) == 1:
        inner = _literal(value.operands[0])
        return -float(inner) if isinstance(inner, (int, float)) else None
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else None


def _literal_str(value) -> str:
    v = _literal(value)
    return v if isinstance(v, str) else ""


def _is_constant(e: ca.SX) -> bool:
    return e.is_constant() or not ca.symvar(e)


def _describe(eq) -> str:
    try:
        return f"{_text(eq.left)} = {_text(eq.right)}"
    except Exception:  # a description is a courtesy for error messages only
        return "<equation>"


def _text(e) -> str:
    if isinstance(e, A.Primary):
        return repr(e.value)
    if isinstance(e, A.ComponentRef):
        return _cref_name(e)
    if isinstance(e, A.Expression):
        op = e.operator if isinstance(e.operator, str) else _cref_name(e.operator)
        if len(e.operands) == 2 and op in {"+", "-", "*", "/", "^", *_RELATIONS}:
            return f"({_text(e.operands[0])} {op} {_text(e.operands[1])})"
        return f"{op}({', '.join(_text(o) for o in e.operands)})"
    if isinstance(e, A.IfExpression):
        return "if ..."
    return type(e).__name__


def _resolve_calculated(calculated, model_name):
    """Order bound parameters so each refers only to independent ones (substituted)."""
    pending = list(calculated)
    resolved: list[tuple[Variable, ca.SX]] = []
    while pending:
        progressed = False
        for item in list(pending):
            var, expr = item
            others = [v.sym for v, _ in pending if v is not var]
            if others and ca.depends_on(expr, ca.vertcat(*others)):
                continue
            if resolved:
                expr = ca.substitute([expr], [v.sym for v, _ in resolved], [e for _, e in resolved])[0]
            resolved.append((var, expr))
            pending.remove(item)
            progressed = True
        if not progressed:
            names = ", ".join(v.name for v, _ in pending)
            raise ModelicaError(f"parameter bindings in {model_name} form a cycle: {names}")
    return resolved


def _substitute_calculated(model: SymbolicModel) -> SymbolicModel:
    """Replace bound parameters by their expressions everywhere they are used."""
    if not model.calculated:
        return model
    syms = [v.sym for v, _ in model.calculated]
    exprs = [e for _, e in model.calculated]

    def sub(items):
        return list(ca.substitute(items, syms, exprs)) if items else items

    model.equations = sub(model.equations)
    model.initial_equations = sub(model.initial_equations)
    for cond in model.conditions:
        cond.event_time = ca.substitute([cond.event_time], syms, exprs)[0]
    return model
