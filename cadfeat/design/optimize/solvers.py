"""Solvers on an ``Evaluator``: local SLSQP / trust-constr with finite-difference gradients, multi-start from
a scrambled Sobol design, differential evolution, NSGA-II (pymoo), and the standard-size snap."""

from __future__ import annotations

import itertools
import warnings
from typing import TYPE_CHECKING, Any

import numpy as np

from cadfeat.design.optimize.evaluator import Evaluator, ParetoFront, StartSummary

if TYPE_CHECKING:  # pragma: no cover
    from cadfeat.design.design_space import DesignSpace
    from cadfeat.design.optimize import OptimizerConfig
    from cadfeat.design.optimize.evaluator import OptimProblem


# -------------------------------------------------------------------------------------------- local
class _LocalFunctions:
    """The local solve's objective and constraints (maximise the combined objective, constraints C ≥ 0) on
    z = u (the free variables' unit coordinates), with finite-difference Jacobians (``local_solve``)."""

    def __init__(self, ev: Evaluator, config: OptimizerConfig, p: int) -> None:
        self.ev, self.config, self.p = ev, config, p
        self.problem = ev.problem
        self.iteration = 0

    def grads(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        return self.ev.gradients(z[:self.p], self.config.fd_step)

    def values(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """G (K,), C (M,) at z; with ``eager_gradients`` the whole finite-difference stencil is evaluated in
        the same batch (the solver nearly always asks for the gradient where it asked for the value)."""
        if self.config.eager_gradients:
            G, C, _, _ = self.grads(z)
            return G, C
        G, C = self.ev.batch(z[:self.p][None])
        return G[0], C[0]

    def fun(self, z: np.ndarray) -> float:
        return -float(self.problem.combined_from(self.values(z)[0]))

    def fun_jac(self, z: np.ndarray) -> np.ndarray:
        G, _, dG, _ = self.grads(z)
        # combined is linear in G for "weighted"/"constraint": d(combined) = Σ_k ∂combined/∂G_k dG_k
        w = _combine_weights(self.problem, G)
        return -(w @ dG)

    def cons(self, z: np.ndarray) -> np.ndarray:
        return self.values(z)[1]

    def cons_jac(self, z: np.ndarray) -> np.ndarray:
        return self.grads(z)[3]

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds of z."""
        return np.zeros(self.p), np.ones(self.p)

    def callback(self, *args: Any) -> None:
        """Record each solver iterate with the evaluator (``ev.record``)."""
        zk = args[0] if not hasattr(args[0], "x") else args[0].x
        self.iteration += 1
        G, C = self.ev.batch(np.asarray(zk)[:self.p][None])
        self.ev.record(self.iteration, G[0], C[0])


class _EpigraphFunctions(_LocalFunctions):
    """Max-min in epigraph form on z = (u, τ): maximise τ subject to C ≥ 0, ĝ_i(u) − τ ≥ 0 (i in ``use``) and
    ĝ_i(u) − floor_i ≥ 0 (``floors``)."""

    def __init__(self, ev: Evaluator, config: OptimizerConfig, p: int, use: np.ndarray, fl_idx: np.ndarray,
                 fl_val: np.ndarray) -> None:
        super().__init__(ev, config, p)
        self.use, self.fl_idx, self.fl_val = use, fl_idx, fl_val

    def fun(self, z: np.ndarray) -> float:
        return -float(z[self.p])

    def fun_jac(self, z: np.ndarray) -> np.ndarray:
        g = np.zeros(self.p + 1)
        g[self.p] = -1.0
        return g

    def cons(self, z: np.ndarray) -> np.ndarray:
        G, C = self.values(z)
        Gn = self.problem.normalised(G)
        return np.concatenate([C, Gn[self.use] - z[self.p], Gn[self.fl_idx] - self.fl_val])

    def cons_jac(self, z: np.ndarray) -> np.ndarray:
        _, _, dG, dC = self.grads(z)
        use, fl_idx, scales = self.use, self.fl_idx, self.problem.scales
        top = np.hstack([dC, np.zeros((dC.shape[0], 1))])
        bottom = np.hstack([dG[use] / scales[use, None], -np.ones((use.size, 1))])
        fixed = np.hstack([dG[fl_idx] / scales[fl_idx, None], np.zeros((fl_idx.size, 1))])
        return np.vstack([top, bottom, fixed])

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return np.append(np.zeros(self.p), -np.inf), np.append(np.ones(self.p), np.inf)


def local_solve(ev: Evaluator, u0: np.ndarray, config: OptimizerConfig, *, use: np.ndarray | None = None,
                floors: dict[int, float] | None = None) -> np.ndarray:
    """One local solve from u0 (unit coordinates of the free variables); returns the final u.

    Max-min (and Pareto's chosen-point criterion) is solved in epigraph form: maximise τ subject to
    ĝ_i(u) ≥ τ, so the solver sees smooth functions. ``use``: the objectives in the max-min (default the
    combined ones); ``floors``: objective index → lower bound ĝ_i ≥ floor (leximin's fixed objectives).
    Gradients: central differences, step ``config.fd_step`` relative to each variable's range, value and
    Jacobians from one batch."""
    problem = ev.problem
    use = np.asarray(problem.combined_idx if use is None else use, dtype=int)
    floors = floors or {}
    fl_idx = np.array(sorted(floors), dtype=int)
    fl_val = np.array([floors[i] for i in fl_idx], dtype=float)
    epigraph = problem.objective_config.combine in ("maxmin", "pareto") and (use.size > 1 or bool(floors))
    p = u0.size
    if epigraph:
        f: _LocalFunctions = _EpigraphFunctions(ev, config, p, use, fl_idx, fl_val)
        G0, _ = ev.batch(u0[None])
        tau0 = float(problem.normalised(G0[0])[use].min())
        z0 = np.append(u0, tau0)
    else:
        f = _LocalFunctions(ev, config, p)
        z0 = np.asarray(u0, dtype=float)
    n_cons = ev.batch(z0[:p][None])[1].shape[1] + (use.size + fl_idx.size if epigraph else 0)
    return _minimize(f, z0, n_cons, config)


def _minimize(f: _LocalFunctions, z0: np.ndarray, n_cons: int, config: OptimizerConfig) -> np.ndarray:
    """``scipy.optimize.minimize`` (``config.local_solver``: SLSQP or trust-constr) of ``f`` from z0 with
    ``n_cons`` constraints; the final u clipped to the unit box."""
    from scipy.optimize import Bounds, NonlinearConstraint, minimize

    constraints = []
    if n_cons:
        if config.local_solver == "SLSQP":
            constraints = [{"type": "ineq", "fun": f.cons, "jac": f.cons_jac}]
        else:
            constraints = [NonlinearConstraint(f.cons, 0.0, np.inf, jac=f.cons_jac)]
    options = {"maxiter": config.maxiter}
    if config.local_solver == "SLSQP":
        options["ftol"] = config.ftol
    else:
        options.update(gtol=config.ftol, xtol=config.ftol)
    lb, ub = f.bounds()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = minimize(f.fun, z0, jac=f.fun_jac, method=config.local_solver, bounds=Bounds(lb, ub),
                       constraints=constraints, callback=f.callback, options=options)
    return np.clip(np.asarray(res.x)[:f.p], 0.0, 1.0)


def _combine_weights(problem: OptimProblem, G: np.ndarray) -> np.ndarray:
    """∂combined/∂G (K,) at G by finite differences of ``combined_from`` (exact for the linear combinations)."""
    K = G.size
    eps = 1e-6 * np.maximum(np.abs(G), problem.scales)
    Gp = G + np.diag(eps)
    Gm = G - np.diag(eps)
    return (np.asarray(problem.combined_from(Gp)) - np.asarray(problem.combined_from(Gm))) / (2 * eps)[:K]


def leximin_refine(ev: Evaluator, config: OptimizerConfig, tol: float = 1e-8) -> None:
    """Break max-min ties by leximin: from the best design, fix the worst normalised objective at its value
    (− ``tol``) and maximise the smallest of the others, then the next, ... (K' − 1 local solves). The
    evaluator's best design is compared leximin-wise (``Evaluator._consider``), so the result is the
    leximin-better of the max-min optimum and its refinements."""
    problem = ev.problem
    if problem.objective_config.combine != "maxmin" or ev.best is None:
        return
    remaining = [int(i) for i in problem.combined_idx]
    floors: dict[int, float] = {}
    phase = ev.phase
    ev.phase = "leximin"
    while len(remaining) > 1:
        Gn = problem.normalised(ev.best["G"])
        worst = min(remaining, key=lambda i: Gn[i])
        floors[worst] = float(Gn[worst]) - tol
        remaining.remove(worst)
        local_solve(ev, ev.to_u(ev.best["x"]), config, use=np.array(remaining), floors=dict(floors))
    ev.phase = phase


# ----------------------------------------------------------------------------------------- starts
def sobol_starts(p: int, n: int, seed: int) -> np.ndarray:
    """``n`` points of a scrambled Sobol sequence in [0, 1]^p (seeded)."""
    from scipy.stats import qmc

    if n <= 0:
        return np.zeros((0, p))
    m = int(np.ceil(np.log2(max(n, 1))))
    return qmc.Sobol(d=p, scramble=True, seed=seed).random_base2(m)[:n]


def multistart(ev: Evaluator, config: OptimizerConfig) -> list[StartSummary]:
    """Local solves from ``config.starts`` points of a seeded Sobol design of the search box (they cover it
    whatever the initial design), then from the initial design as one extra start; one summary per start.

    The initial design comes last so that it never decides a tie: the best design so far is replaced only by a
    strictly better one (``Evaluator._consider``), so among equally good optima the Sobol starts' is kept and
    the answer does not depend on where the part's current values happen to be (issue 16)."""
    u0 = ev.to_u(ev.x_base)
    starts = np.vstack([sobol_starts(u0.size, config.starts, config.seed), u0[None]])
    summaries: list[StartSummary] = []
    for k, u in enumerate(starts):
        ev.start = k
        u_end = local_solve(ev, u, config)
        G, C = ev.batch(u_end[None])
        summaries.append({"start": k, "x_start": ev.to_x(u[None])[0].tolist(),
                          "x_end": ev.to_x(u_end[None])[0].tolist(),
                          "combined": float(ev.problem.combined_from(G[0])),
                          "max_violation": float(max(0.0, -C[0].min(initial=0.0)))})
    return summaries


# ---------------------------------------------------------------------------------------- global
def global_solve(ev: Evaluator, config: OptimizerConfig) -> np.ndarray:
    """``scipy.optimize.differential_evolution`` (seeded) on the combined objective with the margins as
    constraints, then a local polish from its best point."""
    from scipy.optimize import NonlinearConstraint, differential_evolution

    p = ev.free.size
    n_cons = ev.batch(ev.to_u(ev.x_base)[None])[1].shape[1]
    constraints = (NonlinearConstraint(lambda u: ev.batch(u[None])[1][0], 0.0, np.inf),) if n_cons else ()
    generation = [0]

    def callback(intermediate_result: Any) -> None:
        generation[0] += 1
        G, C = ev.batch(np.asarray(intermediate_result.x)[None])
        ev.record(generation[0], G[0], C[0])

    ev.phase = "global"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = differential_evolution(lambda u: -float(ev.combined(u[None])[0]), [(0.0, 1.0)] * p,
                                     constraints=constraints, seed=config.seed, maxiter=config.de_maxiter,
                                     popsize=config.de_popsize, polish=False, callback=callback, tol=1e-8)
    ev.phase = "polish"
    return local_solve(ev, np.asarray(res.x), config)


# ---------------------------------------------------------------------------------------- Pareto
def pareto_solve(ev: Evaluator, config: OptimizerConfig) -> ParetoFront:
    """NSGA-II (pymoo, seeded) on the normalised objectives; the front and its max-min point."""
    from pymoo.algorithms.moo.nsga2 import NSGA2
    from pymoo.core.callback import Callback
    from pymoo.core.problem import Problem as PymooProblem
    from pymoo.optimize import minimize

    problem = ev.problem
    use = np.asarray(problem.combined_idx, dtype=int)
    n_cons = ev.batch(ev.to_u(ev.x_base)[None])[1].shape[1]

    class _P(PymooProblem):
        def __init__(self) -> None:
            super().__init__(n_var=ev.free.size, n_obj=use.size, n_ieq_constr=n_cons, xl=0.0, xu=1.0)

        def _evaluate(self, U: np.ndarray, out: dict[str, np.ndarray], *args: object, **kwargs: object) -> None:
            G, C = ev.batch(U)
            out["F"] = -problem.normalised(G)[:, use]
            if n_cons:
                out["G"] = -C

    class _CB(Callback):
        def notify(self, algorithm: Any) -> None:
            opt = algorithm.opt
            X = opt.get("X")
            G, C = ev.batch(X)
            best = int(np.argmax(problem.combined_from(G)))
            ev.record(algorithm.n_gen, G[best], C[best], front_size=len(X))

    ev.phase = "pareto"
    res = minimize(_P(), NSGA2(pop_size=config.pop_size), ("n_gen", config.n_gen), seed=config.seed,
                   callback=_CB(), verbose=False)
    X = res.X if res.X is not None else res.pop.get("X")
    X = np.atleast_2d(X)
    G, C = ev.batch(X)
    feasible = np.all(C >= -1e-6, axis=1) if C.shape[1] else np.ones(len(X), dtype=bool)
    order = np.lexsort(tuple(problem.normalised(G)[:, use].T[::-1]))
    X, G, C, feasible = X[order], G[order], C[order], feasible[order]
    crit = np.where(feasible, problem.combined_from(G), -np.inf)
    chosen = int(np.argmax(crit))
    return {"names": [problem.names[i] for i in use], "points": G[:, use].tolist(),
            "normalised": problem.normalised(G)[:, use].tolist(), "x": ev.to_x(X).tolist(),
            "feasible": feasible.tolist(), "chosen": chosen, "chosen_by": "max-min of the normalised objectives"}


# ------------------------------------------------------------------------------------------- snap
def snap_candidates(space: DesignSpace, x: np.ndarray, max_combinations: int = 16) -> list[np.ndarray]:
    """Designs with every standard-size variable at one of its two nearest sizes (all combinations when at
    most ``max_combinations``, else the nearest size only)."""
    disc = np.flatnonzero(space.discrete)
    options: list[np.ndarray] = []
    for i in disc:
        sizes = np.asarray(space.variables[i].standard_sizes, dtype=float)
        order = np.argsort(np.abs(sizes - x[i]), kind="stable")
        options.append(sizes[order[:2]])
    if np.prod([len(o) for o in options]) > max_combinations:
        options = [o[:1] for o in options]
    out: list[np.ndarray] = []
    for combo in itertools.product(*options):
        y = np.array(x, dtype=float)
        y[disc] = combo
        out.append(y)
    return out
