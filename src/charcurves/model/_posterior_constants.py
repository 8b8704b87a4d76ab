"""The constants of the closed forms with their posterior standard deviations, for
``model.to_sympy(uncertainty=True)`` and ``model.to_latex(uncertainty=True)``.

A curve's closed form has numbers (sympy ``Float``); the posterior gives the curve's values as
``value(z) + G(z) u`` (``curve_factor``). Where the closed form moves with its constants as the
posterior moves the curve (a basis fit: each constant multiplies a basis function, so the
Jacobian ``Phi(z) = d f / d theta`` spans ``G``), the constants' posterior is ``theta + Phi^+ G u``,
exactly. A closed form whose Jacobian does not span ``G`` gets no ± on its constants.
The gain, the free constant and the scalars take theirs from ``scalar_stats``.
"""

from __future__ import annotations

import numpy as np

from .._lambdify import numpy_function

__all__ = ["PlusMinus", "constant_sds", "constant_sds_of", "uncertain_parts", "closed_form_lines"]

#: How far ``Phi Theta`` may miss ``G`` (relative, Frobenius) for the constants to carry the posterior.
SPAN_TOLERANCE = 1e-6


def PlusMinus(mean: float, sd: float):
    """A sympy symbol printed as ``(mean ± sd)`` (LaTeX ``(mean \\pm sd)``), 1 sd, to the digits the sd supports.

    Examples
    --------
    >>> import sympy as sp
    >>> from charcurves.model import PlusMinus
    >>> z = sp.Symbol("z")
    >>> e = PlusMinus(0.29912, 0.0041) * z * sp.Abs(z)
    >>> print(str(e), "|", sp.latex(e))
    (0.2991 ± 0.0041)*z*Abs(z) | (0.2991 \\pm 0.0041) z \\left|{z}\\right|
    """
    import sympy as sp

    from ._posterior import _pm

    text = _pm(float(mean), float(sd))
    return _symbol_class(sp)(f"({text})", real=True)


_CLASS: list = []


def _symbol_class(sp):
    if not _CLASS:
        class PlusMinusSymbol(sp.Symbol):  # its class name sorts it before the Symbols it multiplies
            def _latex(self, printer):
                return self.name.replace("±", "\\pm").replace(" inf", " \\infty")

        _CLASS.append(PlusMinusSymbol)
    return _CLASS[0]


def constant_sds(model, name: str, post) -> dict | None:
    """``{Float: sd}`` of curve ``name``'s closed-form constants under ``post``; None where its Jacobian does
    not span the posterior (or the curve has no closed form, or ``post`` gives no linear map)."""
    import sympy as sp

    post = getattr(post, "inner", post)  # a lack-of-fit term widens the band, not the constants' posterior
    curve = model.curves[name]
    expr = curve.expression()
    if expr is None or not hasattr(post, "curve_factor"):
        return None
    floats = sorted(expr.atoms(sp.Float), key=lambda f: (abs(float(f)), float(f)))
    if not floats:
        return {}
    z = sp.Symbol("z", real=True)  # the derivative of Abs(z) is sign(z) on a real z (numpy can print it)
    thetas = sp.symbols(f"theta0:{len(floats)}", real=True)
    param = expr.xreplace({sp.Symbol("z"): z, **dict(zip(floats, thetas))})
    grid = np.linspace(curve.domain[0], curve.domain[1], 101)
    _, G, infinite = post.curve_factor(name, grid)
    values = [float(f) for f in floats]
    try:
        with np.errstate(all="ignore"):
            Phi = np.column_stack([np.broadcast_to(np.asarray(numpy_function([z, *thetas], sp.diff(param, th))(
                grid, *values), dtype=float), grid.shape) for th in thetas])
    except (TypeError, ValueError, NameError, NotImplementedError):  # a derivative numpy cannot evaluate
        return None
    if not np.all(np.isfinite(Phi)):
        return None
    Theta, *_ = np.linalg.lstsq(Phi, G, rcond=None)
    miss = np.linalg.norm(Phi @ Theta - G)
    if miss > SPAN_TOLERANCE * (np.linalg.norm(G) + 1e-300) + 1e-300:
        return None
    sd = np.sqrt(np.sum(Theta**2, axis=1))
    if np.any(infinite):  # a direction the record does not determine: what loads on it is unknown
        touched = np.abs(np.linalg.pinv(Phi)[:, infinite]).max(axis=1) > 0
        sd = np.where(touched, np.inf, sd)
    return dict(zip(floats, sd.tolist()))


def constant_sds_of(model, name: str) -> dict | None:
    """``{Float: sd}`` (1 sd) of the numbers in curve ``name``'s closed form under the model's posterior;
    None where it has none or the closed form does not carry it (module docstring).

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.model import constant_sds_of
    >>> from charcurves.systems import get_system
    >>> record = cc.corrupt(get_system("duffing").simulate(), 20, seed=0)
    >>> model = cc.fit(record, method="parametric", basis="f1=z; f2=z, z**3")
    >>> {f"{float(c):.3f}": f"{sd:.4f}" for c, sd in constant_sds_of(model, "f1").items()}
    {'0.303': '0.0023'}
    """
    from ._posterior import model_posterior

    post = model_posterior(model)
    return None if post is None else constant_sds(model, name, post)


def uncertain_parts(model, digits: int | None):
    """``(exprs, num)`` for :meth:`FittedModel.to_sympy` with ± on the constants that have a posterior:
    each curve's closed form with its constants as :func:`PlusMinus` symbols, and a ``num(value,
    constant)`` that writes the gain, the free constant and the scalars with theirs."""
    import sympy as sp

    from .._errors import ConfigError
    from ._display import curve_scale, display_number
    from ._posterior import model_posterior

    post = model_posterior(model)
    if post is None:
        raise ConfigError(f"this {model.method} model has no posterior, so its constants have no ±; fit with a "
                          "method that has one (poly-cc, parametric, sindy-cc, nn-cc, nn-cc+sym, by equation or "
                          "output error, and post-SR closed forms), or drop uncertainty=True")
    scale = curve_scale(model)

    def plain(value: float, constant: bool = False):
        return sp.Float(value) if digits is None else display_number(value, scale if constant else 0.0, digits)

    def pm(value: float, sd: float):
        return PlusMinus(value, sd) if value >= 0 else -PlusMinus(-value, sd)

    exprs: dict = {}
    for name, curve in model.curves.items():
        expr = curve.expression()
        if expr is None:
            exprs[name] = None
            continue
        sds = constant_sds(model, name, post)
        exprs[name] = expr.xreplace({f: (pm(float(f), sds[f]) if sds is not None else plain(float(f), True))
                                     for f in expr.atoms(sp.Float)})
    stats = post.scalar_stats()
    known = [(stats["mean"][k], stats["sd"][k]) for k in stats["names"]]

    def num(value: float, constant: bool = False):
        for mean, sd in known:
            if np.isclose(value, mean, rtol=1e-9, atol=0.0):
                return pm(float(value), sd)
        return plain(value, constant)

    return exprs, num


def closed_form_lines(model) -> list[str]:
    """summary.txt lines: each closed form with its constants' posterior sd (1 sd), where it has them.

    Examples
    --------
    >>> import charcurves as cc
    >>> from charcurves.model import closed_form_lines
    >>> from charcurves.systems import get_system
    >>> record = cc.corrupt(get_system("duffing").simulate(), 20, seed=0)
    >>> print(closed_form_lines(cc.fit(record, method="parametric", basis="f1=z; f2=z, z**3"))[0])
      f1(z) = (0.3033 ± 0.0023)*z (1 sd, posterior)
    """
    from ._posterior import model_posterior

    post = model_posterior(model)
    if post is None:
        return []
    exprs, _ = uncertain_parts(model, None)
    out = []
    for name, expr in exprs.items():
        sds = constant_sds(model, name, post) if expr is not None else None
        if sds:
            out.append(f"  {name}(z) = {expr} (1 sd, posterior)")
    return out
