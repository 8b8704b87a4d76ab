"""The forced Duffing oscillator (chaotic at the benchmark parameters)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from typing import Any, ClassVar

import numpy as np

from ._base import BenchmarkSystem, _in_box, sample_times, solver_failed

__all__ = ["Duffing"]

_COMMON = {"delta": 0.3, "A": 0.5, "Omega": 1.2, "x0": 0.5, "v0": -0.5}


@dataclasses.dataclass(frozen=True, kw_only=True)
class Duffing(BenchmarkSystem):
    """Duffing oscillator ``x'' + δ x' + α x + β x³ = A cos(Ω t)``.

    Notes
    -----
    Variants:

    ``"paper"`` (default)
        α = −1, β = 1 (the paper's text and its Fig. 4 data), tight tolerances (rtol 1e-10,
        atol 1e-12): a reference trajectory that does not depend on the solver.
    ``"scripts"``
        α = −1.05, β = 1.02 (the authors' figure scripts) with LSODA's default tolerances
        (rtol 1e-3, atol 1e-6), which reproduces the scripts' data.

    Both: δ = 0.3, A = 0.5, Ω = 1.2, x0 = 0.5, v0 = −0.5. Any field can be overridden, e.g.
    ``Duffing(tolerance="scipy-default")`` for the paper's parameters with the scripts' solver.

    Examples
    --------
    >>> from charcurves.systems import Duffing
    >>> tr = Duffing().simulate()
    >>> tr.n_samples, tr.name
    (1000, 'duffing')
    """

    name: ClassVar[str] = "duffing"
    VARIANTS: ClassVar[dict[str, dict[str, Any]]] = {
        "paper": {"alpha": -1.0, "beta": 1.0, "tolerance": "tight", **_COMMON},
        "scripts": {"alpha": -1.05, "beta": 1.02, "tolerance": "scipy-default", **_COMMON},
    }
    _PARAMETER_FIELDS: ClassVar[tuple[str, ...]] = ("alpha", "beta", "delta", "A", "Omega", "x0", "v0")

    alpha: float | None = None
    beta: float | None = None
    delta: float | None = None

    def f1(self, v: Any) -> np.ndarray:
        """Damping curve f1(v) = δ v."""
        return self.delta * np.asarray(v, dtype=float)

    def f2(self, x: Any) -> np.ndarray:
        """Stiffness curve f2(x) = α x + β x³."""
        x = np.asarray(x, dtype=float)
        return self.alpha * x + self.beta * x**3

    def _plain_rhs(self) -> Callable[[float, np.ndarray], list[float]]:
        """The right-hand side ``(t, (x, v)) -> (x', x'')`` of this system's own initial state and forcing."""
        A, Om, d, al, be = self.A, self.Omega, self.delta, self.alpha, self.beta
        assert A is not None and Om is not None and d is not None and al is not None and be is not None

        # Plain floats: LSODA calls this once per stage, numpy scalars would be ~5x slower.
        def rhs(t: float, y: np.ndarray) -> list[float]:
            x, v = float(y[0]), float(y[1])
            return [v, A * math.cos(Om * t) - d * v - al * x - be * x**3]

        return rhs

    def _integrate(self, t_eval: np.ndarray, rtol: float, atol: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        rhs = self._plain_rhs()
        from scipy.integrate import solve_ivp  # lazily: importing the systems stays light
        sol = solve_ivp(
            rhs, (t_eval[0], t_eval[-1]), [self.x0, self.v0], method="LSODA",
            t_eval=t_eval, rtol=rtol, atol=atol,
        )
        if not sol.success or sol.y.shape[1] != t_eval.size:
            raise solver_failed(self.name, sol.message)
        x, v = sol.y
        return x, v, self.acceleration(t_eval, x, v)

    def simulate_many(self, t_eval: Any, draws: Sequence[Mapping[str, float]],
                      box: Mapping[str, tuple[float, float]] | None = None) -> Iterator[tuple | None]:
        """At the tight tolerances the draws are integrated stacked in one LSODA run (one state of
        2 x draws components, its error control over all of them): about five times cheaper than
        one by one for validation draws (64 draws of 80 s in 0.25 s against 3.5 s). Each trajectory
        is as accurate as its own run, to the tolerances, but not the same bits: over 80 s of this
        chaotic system the two differ by up to about 1e-2 at the end (1e-6 over the first 20 s). At
        the scripts' loose tolerances the draws are integrated one by one, as the scripts do.

        Examples
        --------
        >>> import numpy as np
        >>> from charcurves.systems import get_system
        >>> system = get_system("duffing")
        >>> t = np.linspace(0.0, 20.0, 201)
        >>> draws = [{"x0": 0.5, "v0": -0.5, "A": 0.5, "Omega": 1.2}, {"x0": 0.0, "v0": 0.3, "A": 0.4, "Omega": 1.1}]
        >>> runs = list(system.simulate_many(t, draws))
        >>> bool(np.max(np.abs(runs[1][0] - system.simulate(t_eval=t, **draws[1]).x)) < 1e-6)
        True
        """
        if self.tolerance != "tight" or len(draws) < 2:
            yield from super().simulate_many(t_eval, draws, box)
            return
        t_eval = sample_times(t_eval=t_eval)
        d, al, be = self.delta, self.alpha, self.beta
        assert d is not None and al is not None and be is not None
        A = np.array([float(w["A"]) for w in draws])
        W = np.array([float(w["Omega"]) for w in draws])
        k = len(draws)

        def rhs(t: float, y: np.ndarray) -> np.ndarray:
            x, v = y[:k], y[k:]
            return np.concatenate([v, A * np.cos(W * t) - d * v - al * x - be * x**3])

        from scipy.integrate import solve_ivp

        y0 = [float(w["x0"]) for w in draws] + [float(w["v0"]) for w in draws]
        sol = solve_ivp(rhs, (t_eval[0], t_eval[-1]), y0, method="LSODA", t_eval=t_eval, rtol=self.rtol,
                        atol=self.atol)
        if not sol.success or sol.y.shape[1] != t_eval.size or not np.isfinite(sol.y).all():
            yield from super().simulate_many(t_eval, draws, box)
            return
        for i in range(k):
            x, v = sol.y[i], sol.y[k + i]
            yield (x, v) if box is None or _in_box(x, v, box) else None
