"""The representations of the paper's methods: Neural (NN-CC), SparseLibrary (SINDy-CC), Basis
(Parametric) and Symbolic (SR-CC); Polynomial (Poly-CC) lives in :mod:`._polynomial`."""

from __future__ import annotations

import numpy as np

from .._errors import ConfigError
from ._base import AbstractCurve, LinearCurve, normalise_symmetry
from ._input_map import neural_input_map
from ._loadable import remember_curve

__all__ = ["Neural", "SparseLibrary", "Basis", "Symbolic", "SPARSE_OPTIMIZERS"]


class Neural(AbstractCurve):
    """A small neural network per curve (NN-CC), with exact parity and an optional learned jump.

    ``f(u) = sym[MLP(u)] + c u + mu tanh(u / eps)`` on the scaled argument ``u = z / max|z|``
    (see :class:`~charcurves.curves.NeuralCurve` for the composition rule).

    Parameters
    ----------
    hidden : tuple of int, optional
        Hidden layer widths; default the training preset's (one layer of 8 units).
    activation : {"softplus", "tanh", "relu", "gelu", "silu"}, optional
        Default the training preset's.
    symmetry : {None, "odd", "even"}
        Parity prior, built into the network exactly (or as the paper's penalty under the
        ``paper`` training preset).
    jump : bool or "auto"
        A learned jump at 0 (dry friction). "auto": added when the record has sticking phases or
        a least-squares test finds a jump at zero velocity significant (velocity curves only).
    powers : tuple of int or "auto", optional
        Polynomial terms beside the network (see :class:`~charcurves.curves.NeuralCurve`); "auto"
        (the default preset's): a quadratic (even or unconstrained curves) and a cubic (odd or
        unconstrained curves) term, each where a least-squares F test on the record finds it
        significant, none beside a jump.
    harmonics : tuple of float or "auto", optional
        Angular frequencies ``w`` (per unit of the curve's argument ``z``) of harmonic terms
        ``a sin(w z) + b cos(w z)`` beside the network; "auto" (the default preset's): the
        frequencies a periodogram of the equation error finds significant (a curve that oscillates
        over many periods of its argument, see ``charcurves.fitting.harmonic_test``), none otherwise.

    Examples
    --------
    >>> from charcurves.curves import Neural
    >>> Neural(symmetry="odd")
    Neural(symmetry='odd')
    """

    kind = "neural"

    def __init__(self, hidden=None, activation: str | None = None, symmetry: str | None = None, jump=False,
                 powers=None, harmonics=None):
        self.hidden = hidden
        self.activation = activation
        self.symmetry = symmetry
        self.jump = jump
        self.powers = powers
        self.harmonics = harmonics

    def check(self) -> None:
        sym = normalise_symmetry(self.symmetry, "Neural")
        if self.hidden is not None:
            try:
                widths = tuple(int(h) for h in self.hidden)
            except (TypeError, ValueError):
                widths = ()
            if not widths or min(widths) < 1 or any(isinstance(h, bool) for h in self.hidden):
                raise ConfigError(f"Neural hidden must be a tuple of positive layer widths such as (8,) or (16, 16), "
                                  f"got {self.hidden!r}")
        if self.harmonics is not None and self.harmonics != "auto":
            try:
                ws = [float(w) for w in self.harmonics]
            except (TypeError, ValueError):
                ws = [-1.0]
            if any(not np.isfinite(w) or w <= 0 for w in ws):
                raise ConfigError(f"Neural harmonics must be 'auto' or a tuple of positive angular frequencies, "
                                  f"got {self.harmonics!r}")
        if self.jump not in (False, True, "auto"):
            raise ConfigError(f"Neural jump must be False, True or 'auto', got {self.jump!r}")
        if self.jump is True and sym == "even":
            raise ConfigError("a jump at 0 is odd and cannot be part of an even curve; drop the jump or the even prior")
        self.network(None)  # validates the activation

    def network(self, preset, jump: bool | None = None, powers: tuple | None = None,
                harmonics: tuple | None = None):
        """The :class:`~charcurves.curves.NeuralCurve` parametrisation under a training preset
        (``jump``, ``powers`` and ``harmonics`` as decided for a record; ``harmonics`` in the scaled
        argument, as the network sees it)."""
        from ._neural import NeuralCurve

        hidden = tuple(self.hidden) if self.hidden is not None else (preset.hidden if preset is not None else (8,))
        activation = self.activation or (preset.activation if preset is not None else "softplus")
        return NeuralCurve(hidden=hidden, activation=activation, symmetry=self.symmetry_name,
                           symmetry_mode=preset.symmetry_mode if preset is not None else "exact",
                           linear_term=preset.linear_term if preset is not None else True,
                           jump=bool(self.jump is True if jump is None else jump),
                           powers=tuple(powers) if powers is not None else self._fixed_powers(preset),
                           harmonics=tuple(harmonics) if harmonics is not None else ())

    def powers_setting(self, preset):
        """The polynomial terms asked for: a tuple, or "auto" (decided per record by the fitter)."""
        if self.powers is not None:
            return self.powers if self.powers == "auto" else tuple(self.powers)
        return preset.powers if preset is not None else ()

    def harmonics_setting(self, preset):
        """The harmonic frequencies asked for (per unit of ``z``): a tuple, or "auto"."""
        if self.harmonics is not None:
            return self.harmonics if self.harmonics == "auto" else tuple(float(w) for w in self.harmonics)
        return preset.harmonics if preset is not None else ()

    def _fixed_powers(self, preset) -> tuple:
        p = self.powers_setting(preset)
        return () if p == "auto" else tuple(p)

    def scaling(self, z, preset, jump: bool | None = None):
        """``(center, half_width)`` of ``u = (z - center) / half_width``: ``(0, max|z|)`` when the
        argument's range contains 0 or the curve keeps a point at 0 (a parity prior, a jump: ``jump``
        as decided for the record, default the setting), else the range's midpoint and half width
        (see :func:`~charcurves.curves.neural_input_map`)."""
        if preset is not None and not preset.scale_inputs:
            return 0.0, 1.0
        jump = self.jump is True if jump is None else jump
        return neural_input_map(z, anchored=self.symmetry_name != "none" or bool(jump))

    def parametrisation(self, preset):
        return self.network(preset)

    def fitted(self, name, argument, domain, theta, center, half_width, out_scale, constant: float = 0.0, *,
               network=None):
        from ._fitted import NeuralFittedCurve

        return NeuralFittedCurve(name, argument, domain, network if network is not None else self.network(None),
                                 theta, half_width, out_scale, constant, in_center=center)


#: Sparse-regression optimizers of pysindy that SparseLibrary curves use.
SPARSE_OPTIMIZERS = ("constrained-sr3", "stlsq", "sr3")
#: SparseLibrary's maps: "max-abs" (z / max|z| and the target over its RMS: unit-free), "none" (the scripts' raw powers).
SPARSE_RESCALINGS = ("max-abs", "none")


class SparseLibrary(LinearCurve):
    """A sparse library of powers of the argument (SINDy-CC), solved by pysindy's optimizers.

    Parameters
    ----------
    degree : int
        Powers ``z, z^2, ..., z^degree`` (odd or even ones only under a parity prior); the paper: 10.
    symmetry : {None, "odd", "even"}
    optimizer : {"constrained-sr3", "stlsq", "sr3"}, optional
        Default: pysindy's ``ConstrainedSR3`` (l0, the input gain fixed by an equality constraint)
        for a fixed gain, ``STLSQ`` for a free gain (the paper's SINDy).
    threshold : float, optional
        l0 threshold (SR3 family, default 1e-5, mapped to pysindy 2's ``reg_weight_lam``) or the
        STLSQ threshold (default 1e-4).
    alpha, nu, tol, max_iter
        STLSQ ridge, SR3 relaxation, tolerance and iterations.
    rescaling : {"max-abs", "none"}
        ``"max-abs"`` (default): the library is built on ``z / max|z|`` and the regression is scaled by
        the RMS of its target, so that the threshold, ``nu`` and ``tol`` are relative and the fit does
        not depend on the units of the record; ``"none"``: raw powers of ``z`` and the raw target, as
        in the paper's scripts (the threshold in the record's units).

    Notes
    -----
    All SparseLibrary curves of one fit share one sparse regression; their optimizer settings
    must agree.

    Examples
    --------
    >>> from charcurves.curves import SparseLibrary
    >>> library = SparseLibrary(degree=7, symmetry="odd")
    >>> library.powers(), library.resolved_optimizer(free_gain=False), library.resolved_threshold(free_gain=True)
    ([1, 3, 5, 7], 'constrained-sr3', 0.0001)
    """

    def __init__(self, degree: int = 10, symmetry: str | None = None, optimizer: str | None = None,
                 threshold: float | None = None, alpha: float = 0.05, nu: float = 1.0, tol: float = 1e-5,
                 max_iter: int = 10000, rescaling: str = "max-abs"):
        self.degree = degree
        self.rescaling = rescaling
        self.symmetry = symmetry
        self.optimizer = optimizer
        self.threshold = threshold
        self.alpha = alpha
        self.nu = nu
        self.tol = tol
        self.max_iter = max_iter

    def check(self) -> None:
        normalise_symmetry(self.symmetry, "SparseLibrary")
        if self.rescaling not in SPARSE_RESCALINGS:
            raise ConfigError(f"unknown SparseLibrary rescaling {self.rescaling!r}; choose one of "
                              f"{', '.join(SPARSE_RESCALINGS)}")
        if self.optimizer is not None and self.optimizer not in SPARSE_OPTIMIZERS:
            raise ConfigError(f"unknown SparseLibrary optimizer {self.optimizer!r}; choose one of "
                              f"{', '.join(SPARSE_OPTIMIZERS)}")
        for key in ("threshold", "alpha", "nu", "tol"):
            v = getattr(self, key)
            if v is None and key == "threshold":
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) or not np.isfinite(v) \
                    or v < 0 or (key in ("nu", "tol") and v == 0):
                raise ConfigError(f"SINDy option {key} must be a {'positive' if key in ('nu', 'tol') else 'non-negative'}"
                                  f" number, got {v!r}")
        for key, lo, hi in (("degree", 1, 20), ("max_iter", 1, 10**7)):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not lo <= int(v) <= hi:
                raise ConfigError(f"SINDy option {key} must be an integer from {lo} to {hi}, got {v!r}")
        if not self.powers():
            raise ConfigError(f"an {self.symmetry_name} library of degree {self.degree} is empty; raise the degree")

    def powers(self) -> list[int]:
        from ._polynomial import poly_powers

        return poly_powers(int(self.degree), self.symmetry_name)

    def resolved_optimizer(self, free_gain: bool) -> str:
        return self.optimizer or ("stlsq" if free_gain else "constrained-sr3")

    def resolved_threshold(self, free_gain: bool) -> float:
        if self.threshold is not None:
            return float(self.threshold)
        return 1e-4 if self.resolved_optimizer(free_gain) == "stlsq" else 1e-5

    def scaling(self, z, preset=None):
        if self.rescaling == "none":
            return 0.0, 1.0  # pysindy sees the raw powers, as in the paper's scripts
        h = float(np.max(np.abs(np.asarray(z, dtype=float)))) if np.size(z) else 0.0
        return 0.0, (h if np.isfinite(h) and h > 0 else 1.0)  # a pure scaling keeps parity and f(0) = 0

    def monomial_powers(self) -> tuple[int, ...]:
        return tuple(self.powers())

    def features(self, u):
        import torch

        return torch.stack([u**k for k in self.powers()], dim=-1)

    def feature_derivatives(self, u):
        import torch

        return torch.stack([k * u ** (k - 1) if k > 1 else torch.ones_like(u) for k in self.powers()], dim=-1)

    def n_features(self) -> int:
        return len(self.powers())

    @property
    def pinned_at_zero(self) -> bool:
        return True

    def fitted(self, name, argument, domain, theta, center, half_width, out_scale, constant: float = 0.0):
        from ._fitted import BasisFittedCurve

        coef = np.asarray(theta, dtype=float).mean(axis=0) * out_scale
        terms = {k: float(c) / float(half_width) ** k for k, c in zip(self.powers(), coef)}  # powers of z / h -> of z
        if constant:
            terms[0] = float(constant)
        active = sorted(k for k, c in terms.items() if c != 0.0)
        if not active:
            return BasisFittedCurve(name, argument, domain, ["z"], [0.0])
        basis = ["1" if k == 0 else ("z" if k == 1 else f"z**{k}") for k in active]
        return BasisFittedCurve(name, argument, domain, basis, [terms[k] for k in active])


@remember_curve  # loadable as a LinearFittedCurve's representation (a hidden-state fit's Basis curves)
class Basis(LinearCurve):
    """A linear combination of closed-form functions of the argument (Parametric).

    Parameters
    ----------
    functions : str or sequence of str
        Closed forms in ``z`` (the curve's argument), e.g. ``"z, z**3"`` or ``["z", "tanh(50*z)"]``;
        parsed safely (only z, numbers, arithmetic and sin, cos, tanh, exp, log, sqrt, sign, Abs,
        atan, sinh, cosh, tan).

    Examples
    --------
    >>> from charcurves.curves import Basis
    >>> Basis("z, z**3").function_list()
    ['z', 'z**3']
    """

    def __init__(self, functions="z"):
        self.functions = functions

    def function_list(self) -> list[str]:
        if isinstance(self.functions, str):
            items = [f.strip() for f in self.functions.split(",")]
        elif isinstance(self.functions, (list, tuple)):
            items = [str(f).strip() for f in self.functions]
        else:
            raise ConfigError(f"Basis functions must be a string like 'z, z**3' or a list of strings, got "
                              f"{type(self.functions).__name__}")
        return [f for f in items if f]

    def check(self) -> None:
        from ._expr import expression_cost_problem, parse_basis_function

        funcs = self.function_list()
        if not funcs:
            raise ConfigError("a Basis needs at least one function of z, e.g. Basis('z, z**3')")
        for text in funcs:
            problem = expression_cost_problem(text)
            if problem:
                raise ConfigError(f"basis function {text[:60]!r} {problem}; write a plain closed form such as 'z**3' "
                                  "or 'tanh(50*z)'")
            parse_basis_function(text)

    def _compiled(self):
        cache = getattr(self, "_cache", None)
        key = tuple(self.function_list())
        if cache is None or cache[0] != key:
            import sympy as sp

            from ._expr import parse_basis_function

            z = sp.Symbol("z")
            exprs = [parse_basis_function(f) for f in key]
            # numbers as floats first: torch's functions take no Python numbers (sin(1)*z failed), and a
            # huge integer literal becomes inf (refused by the fit's column check) instead of an overflow
            funcs = [sp.lambdify(z, _numeric(e), modules="torch") for e in exprs]
            derivs = [sp.lambdify(z, _numeric(_derivative(e, z)), modules="torch") for e in exprs]
            pinned = all(sp.simplify(e.subs(z, 0)) == 0 for e in exprs)
            cache = (key, funcs, derivs, pinned)
            self._cache = cache
        return cache

    def scaling(self, z, preset=None):
        return 0.0, 1.0  # the functions are written in the curve's own argument

    def monomial_powers(self) -> tuple[int, ...] | None:
        """The powers when every function is a plain monomial (``1``, ``z``, ``z**k``, as the fitted
        polynomials and libraries write them): those evaluate without sympy."""
        key = tuple(self.function_list())
        cache = getattr(self, "_monomials", None)
        if cache is None or cache[0] != key:
            from ._expr import monomial_power

            powers = [monomial_power(f) for f in key]
            cache = (key, None if any(k is None for k in powers) else tuple(int(k or 0) for k in powers))
            self._monomials = cache
        return cache[1]

    def features(self, u):
        import torch

        powers = self.monomial_powers()
        if powers is not None:
            return _power_table(u, max(powers)).index_select(-1, torch.tensor(powers, device=u.device))
        funcs = self._compiled()[1]
        return torch.stack([torch.broadcast_to(torch.as_tensor(f(u), dtype=u.dtype), u.shape) for f in funcs], dim=-1)

    def feature_derivatives(self, u):
        import torch

        powers = self.monomial_powers()
        if powers is not None:  # k z^(k-1); the constant's 0 times z^0 (no 0 * inf at z = 0)
            k = torch.tensor(powers, device=u.device)
            table = _power_table(u, max(max(powers) - 1, 0))
            return k.to(u.dtype) * table.index_select(-1, (k - 1).clamp_min(0))
        derivs = self._compiled()[2]
        return torch.stack([torch.broadcast_to(torch.as_tensor(d(u), dtype=u.dtype), u.shape) for d in derivs], dim=-1)

    def feature_names(self) -> list[str]:
        return self.function_list()

    def n_features(self) -> int:
        return len(self.function_list())

    @property
    def pinned_at_zero(self) -> bool:
        powers = self.monomial_powers()
        if powers is not None:
            return all(k > 0 for k in powers)
        return bool(self._compiled()[3])

    def fitted(self, name, argument, domain, theta, center, half_width, out_scale, constant: float = 0.0):
        from ._fitted import BasisFittedCurve

        coef = list(np.asarray(theta, dtype=float).mean(axis=0) * out_scale)
        funcs = self.function_list()
        if constant:
            funcs, coef = funcs + ["1"], coef + [float(constant)]
        return BasisFittedCurve(name, argument, domain, funcs, coef)


class Symbolic(AbstractCurve):
    """A closed form found by symbolic regression (SR-CC; the engine is Operon by default).

    Parameters
    ----------
    operators : "auto" or sequence of str
        Operator set of the search; "auto": + - * (and tanh for a velocity curve of a record
        with sticking phases), as the paper.
    joint : bool
        Search all curves of the template as one bivariate expression and decompose it afterwards
        (the paper's SR, method x) instead of the block-coordinate SR-CC loop.
    refit : bool
        SR-CC only: after the loop, refit the outer coefficients of every curve's terms (and the
        constant, and a free gain) jointly by least squares on the equation, keeping the structure
        SR found (method ``"sr-cc+refit"``). False (the default, ``"sr-cc"``) keeps the coefficients
        of each curve's own search, as the paper's SR-CC does.

    Notes
    -----
    Symbolic curves are found, not trained: every curve of a fit must then be Symbolic.

    Examples
    --------
    >>> from charcurves.curves import Symbolic
    >>> from charcurves.templates import Separable
    >>> Separable(f1=Symbolic(operators=["add", "mul", "tanh"]), f2=Symbolic())
    Separable(f1=Symbolic(operators=['add', 'mul', 'tanh']), f2=Symbolic())
    >>> Symbolic(joint=True).kind
    'symbolic'
    >>> Symbolic(refit=True)
    Symbolic(refit=True)
    """

    kind = "symbolic"

    def __init__(self, operators="auto", joint: bool = False, refit: bool = False):
        self.operators = operators
        self.joint = joint
        self.refit = refit

    def check(self) -> None:
        if not isinstance(self.joint, bool):
            raise ConfigError(f"Symbolic joint must be True or False, got {self.joint!r}")
        if not isinstance(self.refit, bool):
            raise ConfigError(f"Symbolic refit must be True or False, got {self.refit!r}")
        if self.joint and self.refit:
            raise ConfigError("Symbolic(joint=True) (SR) already refits when it drops mixed terms; refit=True is for "
                              "SR-CC (joint=False)")
        if self.operators != "auto" and not (isinstance(self.operators, (list, tuple))
                                             and all(isinstance(o, str) for o in self.operators)):
            raise ConfigError(f"Symbolic operators must be 'auto' or a list such as ['add', 'mul', 'tanh'], got "
                              f"{self.operators!r}")

    @property
    def symmetry_name(self) -> str:
        return "none"

    def scaling(self, z, preset=None):
        return 0.0, 1.0

    def parametrisation(self, preset):
        raise ConfigError("Symbolic curves are found by symbolic regression, not trained; use them for every curve "
                          "of a fit (SR-CC), or distil trained curves with post_sr")

    def fitted(self, *args, **kwargs):  # pragma: no cover - the symbolic fitter builds its curves itself
        raise ConfigError("Symbolic curves are built by the symbolic-regression fitter")


def _numeric(expr):
    """``expr`` with functions of numbers (``sin(1)``) and integers beyond 2**53 as floats: torch's
    functions take no Python numbers, and a huge integer would overflow torch (it becomes inf, which
    the fit's column check refuses); every other number is left exactly as parsed."""
    import sympy as sp

    def numeric(a) -> bool:
        if isinstance(a, (sp.Function, sp.Pow)) and not a.free_symbols:  # sin(1), sqrt(2)
            return True
        return isinstance(a, sp.Rational) and (abs(a.p) > 2**53 or a.q > 2**53)

    return expr.replace(numeric, lambda a: sp.Float(a.evalf(17), 17))


def _derivative(expr, z):
    """d expr / dz for a real argument, with the Dirac deltas of jumps (sign, Heaviside) as 0: the
    derivative the sensitivities of output error use away from the jump."""
    import sympy as sp

    zr = sp.Symbol("z_real", real=True)
    d = sp.diff(expr.subs(z, zr), zr)
    d = d.replace(lambda a: isinstance(a, sp.DiracDelta), lambda a: sp.S.Zero)
    if d.has(sp.Derivative):
        raise ConfigError(f"cannot differentiate the basis function {expr}; write it with functions sympy can "
                          "differentiate (sign, abs, tanh, exp, powers ...)")
    return d.subs(zr, z)


def _power_table(u, kmax: int):
    """``u**0 ... u**kmax`` along a new last axis, by repeated multiplication (one cumulative product:
    cheaper than a power per column or a tensor-exponent power on the long arrays of a fit)."""
    import torch

    ones = torch.ones_like(u).unsqueeze(-1)
    if kmax <= 0:
        return ones
    return torch.cat([ones, u.unsqueeze(-1).expand(*u.shape, kmax).cumprod(-1)], dim=-1)
