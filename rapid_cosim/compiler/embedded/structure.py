"""Structural analysis: residual equations -> explicit ODE, outputs and initial state.

Done in SX, where the Jacobian's sparsity is exact: the incidence is matched and put in
block-triangular form (CasADi's Dulmage-Mendelsohn ``btf``), blocks are solved in
dependency order, each one symbolically because every block must be linear in its own
unknowns. A block that is not (a nonlinear algebraic loop) is rejected by name: the FMU
carries no Newton solver, and an iteration silently failing inside a particle filter
would be worse than an error at build time.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import maximum_bipartite_matching

from ...errors import ModelicaError, UnsupportedConstruct
from .symbolic import SymbolicModel


@dataclass
class ExplicitModel:
    """Everything as explicit functions of (x, u, p, c, t)."""

    model: SymbolicModel
    derivatives: ca.SX  # der(x)
    algebraics: ca.SX  # w, in model.algebraics order
    initial_states: ca.SX  # x at the start, a function of (u, p, c, t)


def solve_model(model: SymbolicModel) -> ExplicitModel:
    x = [v.sym for v in model.states]
    w = [v.sym for v in model.algebraics]
    names = [f"der({v.name})" for v in model.states] + [v.name for v in model.algebraics]
    unknowns = model.derivatives + w
    solution = solve_explicit(model.equations, unknowns, names, f"the equations of {model.name}",
                              model.equation_text)
    dx = ca.vertcat(*solution[: len(x)]) if x else ca.SX(0, 1)
    alg = ca.vertcat(*solution[len(x):]) if w else ca.SX(0, 1)
    x0 = _initial_states(model)
    return ExplicitModel(model, dx, alg, x0)


def _initial_states(model: SymbolicModel) -> ca.SX:
    x = [v.sym for v in model.states]
    if not x:
        return ca.SX(0, 1)
    unknowns = x + model.derivatives + [v.sym for v in model.algebraics]
    names = ([v.name for v in model.states] + [f"der({v.name})" for v in model.states]
             + [v.name for v in model.algebraics])
    equations = list(model.equations) + list(model.initial_equations)
    texts = list(model.equation_text) + ["<initial equation>"] * len(model.initial_equations)
    for v in model.states:
        if v.fixed:
            equations.append(v.sym - (v.start or 0.0))
            texts.append(f"{v.name} = start (fixed)")
    for v in model.algebraics:
        if v.fixed and v.start is not None:
            equations.append(v.sym - v.start)
            texts.append(f"{v.name} = start (fixed)")
    if len(equations) > len(unknowns):
        raise ModelicaError(
            f"the initial system of {model.name} has {len(equations)} equations for "
            f"{len(unknowns)} unknowns: remove initial equations or fixed=true start values")
    # States that nothing determines start from their start value, as Modelica tools do.
    for v in model.states:
        if len(equations) == len(unknowns):
            break
        trial = equations + [v.sym - (v.start or 0.0)]
        if _structural_rank(trial, unknowns) > _structural_rank(equations, unknowns):
            equations, texts = trial, texts + [f"{v.name} = start"]
    solution = solve_explicit(equations, unknowns, names, f"the initial system of {model.name}", texts)
    return ca.vertcat(*solution[: len(x)])


def _structural_rank(equations: list[ca.SX], unknowns: list[ca.SX]) -> int:
    return ca.sprank(ca.jacobian(ca.vertcat(*equations), ca.vertcat(*unknowns)).sparsity())


def solve_explicit(equations: list[ca.SX], unknowns: list[ca.SX], names: list[str],
                   what: str, texts: list[str] | None = None) -> list[ca.SX]:
    """Solve 0 = g(z) for z block by block; each z_i as an expression free of z."""
    n_eq, n_z = len(equations), len(unknowns)
    texts = texts or [f"equation {i + 1}" for i in range(n_eq)]
    if n_eq == 0 and n_z == 0:
        return []
    g = ca.vertcat(*equations)
    z = ca.vertcat(*unknowns)
    sparsity = ca.jacobian(g, z).sparsity()
    if n_eq != n_z or ca.sprank(sparsity) < n_z:
        raise ModelicaError(_singularity_report(sparsity, names, texts, what))

    nb, rowperm, colperm, rowblock, colblock, _, _ = sparsity.btf()
    blocks = [(list(rowperm[rowblock[b]:rowblock[b + 1]]), list(colperm[colblock[b]:colblock[b + 1]]))
              for b in range(nb)]
    order = _dependency_order(blocks, sparsity)

    solved_syms: list[ca.SX] = []
    solved_vals: list[ca.SX] = []
    result: list[ca.SX | None] = [None] * n_z
    for b in order:
        rows, cols = blocks[b]
        r = ca.vertcat(*[equations[i] for i in rows])
        zb = ca.vertcat(*[unknowns[j] for j in cols])
        if solved_syms:
            r = ca.substitute(r, ca.vertcat(*solved_syms), ca.vertcat(*solved_vals))
        jac = ca.jacobian(r, zb)
        if ca.depends_on(jac, zb):
            involved = ", ".join(names[j] for j in cols)
            raise UnsupportedConstruct(
                f"nonlinear algebraic loop in {what} (unknowns: {involved}); "
                "the embedded compiler solves linear blocks only")
        r0 = ca.substitute(r, zb, ca.DM.zeros(zb.shape))
        value = -r0 / jac if len(cols) == 1 else ca.solve(jac, -r0)
        for k, j in enumerate(cols):
            result[j] = ca.simplify(value[k]) if len(cols) == 1 else value[k]
            solved_syms.append(unknowns[j])
            solved_vals.append(result[j])
    return result  # type: ignore[return-value]


def _dependency_order(blocks, sparsity: ca.Sparsity) -> list[int]:
    """Topological order of the blocks (each needs only unknowns of earlier blocks)."""
    col_block = {}
    for b, (_, cols) in enumerate(blocks):
        for j in cols:
            col_block[j] = b
    dense = np.array(ca.DM(sparsity, 1)).astype(bool)
    deps = [set() for _ in blocks]
    for b, (rows, _) in enumerate(blocks):
        for i in rows:
            for j in np.flatnonzero(dense[i]):
                if col_block[j] != b:
                    deps[b].add(col_block[j])
    order, done = [], set()
    while len(order) < len(blocks):
        ready = [b for b in range(len(blocks)) if b not in done and deps[b] <= done]
        if not ready:  # cannot happen for a btf; guard against a silent infinite loop
            raise ModelicaError("internal error: blocks of the equation system are cyclic")
        for b in ready:
            order.append(b)
            done.add(b)
    return order


def _singularity_report(sparsity: ca.Sparsity, names, texts, what) -> str:
    dense = csr_matrix(np.array(ca.DM(sparsity, 1)))
    n_eq, n_z = dense.shape
    match_eq = maximum_bipartite_matching(dense, perm_type="column")  # eq -> unknown
    matched_z = set(int(j) for j in match_eq if j >= 0)
    free_z = [names[j] for j in range(n_z) if j not in matched_z]
    extra_eq = [texts[i] for i in range(n_eq) if match_eq[i] < 0]
    parts = [f"{what} is singular: {n_eq} equations for {n_z} unknowns"]
    if free_z:
        parts.append("not determined by any equation: " + ", ".join(free_z[:10]))
    if extra_eq:
        parts.append("equations with nothing left to determine: " + "; ".join(extra_eq[:5]))
    return "; ".join(parts)
