"""Neural characteristic curves: a network, optional linear and jump parts, and a symmetry prior.

A curve acts on a scaled argument ``u = z / scale`` (no shift, so odd/even stay odd/even) and
returns values in units of the target scale. It is one composition rule, not a class per variant:

    f(u) = sym[ MLP(u) ] + c_lin * u + sum_k c_k u^k + sum_w (a_w sin(w u) + b_w cos(w u)) + mu * tanh(u / eps)

``sym`` is the exact parametrisation (odd: (h(u) - h(-u)) / 2, even: (h(u) + h(-u)) / 2) or
the identity when the prior is imposed as the paper's penalty. The linear part is dropped for
even curves and the jump part is odd by construction (Coulomb friction: eps -> 0 is mu*sign).

Even curves need their own start. A hidden unit of (h(u) + h(-u)) / 2 with one hidden layer
depends on its input weight w only through |w| (the unit and its mirror image coincide), so
w = 0 is a stationary point and near it the loss is quadratic, not linear, in w: Gauss-Newton
steps there overshoot, Levenberg-Marquardt rejects them and stalls, and units started near 0
(a third of PyTorch's U(-1, 1) draws lie within 1/3 of it) stay nearly constant. Even curves
therefore start with |w| in [2, 4] (:data:`EVEN_INPUT_WEIGHTS`) and their output layer, which
enters linearly, is started by least squares (:meth:`NeuralCurve.output_layer`), as the linear
part of the other curves is.
"""

from __future__ import annotations

import dataclasses
import math

import torch

from .._errors import ConfigError
from ._mlp import ACTIVATIONS, BatchedMLP

__all__ = ["NeuralCurve", "SYMMETRIES", "jump_log_eps", "EVEN_INPUT_WEIGHTS"]

SYMMETRIES = ("none", "odd", "even")

#: Range of |input weight| that the first layer of exact even curves starts from (inputs are
#: scaled to |u| <= 1). Measured on the Van der Pol-type record (docs/deviations-training.md): from
#: [1, 3] some seeds still stall (2-3 % error), [2, 4] to [3, 6] all reach the unconstrained fit.
EVEN_INPUT_WEIGHTS = (2.0, 4.0)

#: The jump width eps (in scaled units, |u| <= 1 on the data) is kept in [1e-7, 1] by a smooth
#: map of its raw parameter: wider than the data range it only trades with the linear part (and
#: eps -> inf with mu -> inf overflows); narrower than 1e-7 it is a step either way.
_LOG_EPS_LO, _LOG_EPS_HI = math.log(1e-7), 0.0


def jump_log_eps(raw):
    """log(eps) from the raw parameter: identity inside the range, smoothly saturating at its ends
    (torch tensors or numpy arrays).

    Examples
    --------
    >>> import numpy as np
    >>> from charcurves.curves import jump_log_eps
    >>> [f"{eps:.3g}" for eps in np.exp(jump_log_eps(np.log([1e-3, 1e-12, 10.0])))]  # kept in [1e-7, 1]
    ['0.000999', '1e-07', '0.909']
    """
    if isinstance(raw, torch.Tensor):
        sp = torch.nn.functional.softplus
        return _LOG_EPS_HI - sp((_LOG_EPS_HI - _LOG_EPS_LO) - sp(raw - _LOG_EPS_LO))
    import numpy as np

    sp = lambda x: np.logaddexp(0.0, x)  # noqa: E731
    return _LOG_EPS_HI - sp((_LOG_EPS_HI - _LOG_EPS_LO) - sp(np.asarray(raw, dtype=float) - _LOG_EPS_LO))


def _dlog_eps(raw: torch.Tensor) -> torch.Tensor:
    inner = torch.nn.functional.softplus(raw - _LOG_EPS_LO)
    return torch.sigmoid((_LOG_EPS_HI - _LOG_EPS_LO) - inner) * torch.sigmoid(raw - _LOG_EPS_LO)


@dataclasses.dataclass(frozen=True)
class NeuralCurve:
    """Settings of one neural curve.

    Parameters
    ----------
    hidden : tuple of int
        Hidden layer widths.
    activation : {"tanh", "relu", "softplus", "gelu", "silu"}
    symmetry : {"none", "odd", "even"}
    symmetry_mode : {"exact", "penalty"}
        Exact parametrisation (default) or the paper's soft penalty ``lambda * L_sym``.
    linear_term : bool
        Add a linear part ``c * u`` (skipped for even curves), started from least squares.
    jump : bool
        Add ``mu * tanh(u / eps)``, a learned jump at 0 (dry friction).
    powers : tuple of int
        Further polynomial terms ``c_k u^k`` beside the network (k >= 2; under an exact parity only
        the powers of that parity are kept). Free of weight decay, so the network only models what
        a low-order polynomial cannot, which keeps the curve's ends steady where few samples lie.
    harmonics : tuple of float
        Angular frequencies ``w`` (in the scaled argument ``u``) of harmonic terms
        ``a_w sin(w u) + b_w cos(w u)`` beside the network (only the sine under an exact odd prior,
        only the cosine under an even one). Free of weight decay: they carry a curve that oscillates
        over many periods of its argument, which a small network cannot follow.

    Examples
    --------
    >>> from charcurves.curves import NeuralCurve
    >>> spec = NeuralCurve(hidden=(8,), symmetry="odd", powers=(3,))
    >>> spec.n_params, spec.pinned_at_zero, spec.poly_powers
    (27, True, (3,))
    """

    hidden: tuple[int, ...] = (8,)
    activation: str = "tanh"
    symmetry: str = "none"
    symmetry_mode: str = "exact"
    linear_term: bool = True
    jump: bool = False
    powers: tuple[int, ...] = ()
    decay_powers: bool = True
    harmonics: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        if self.symmetry not in SYMMETRIES:
            raise ConfigError(
                f"unknown symmetry {self.symmetry!r}; choose one of {', '.join(SYMMETRIES)}"
            )
        if self.symmetry_mode not in ("exact", "penalty"):
            raise ConfigError(
                f"unknown symmetry mode {self.symmetry_mode!r}; choose 'exact' or 'penalty'"
            )
        if self.activation not in ACTIVATIONS:
            raise ConfigError(
                f"unknown activation {self.activation!r}; choose one of {', '.join(sorted(ACTIVATIONS))}"
            )
        if self.jump and self.symmetry == "even":
            raise ConfigError("a jump at 0 is odd and cannot be part of an even curve; drop --jump or the even prior")
        object.__setattr__(self, "hidden", tuple(int(h) for h in self.hidden))
        powers = tuple(int(k) for k in self.powers)
        if any(k < 2 or k > 12 for k in powers) or len(set(powers)) != len(powers):
            raise ConfigError(f"powers must be distinct integers from 2 to 12, got {self.powers!r}")
        object.__setattr__(self, "powers", powers)
        harmonics = tuple(float(w) for w in self.harmonics)
        if any(not math.isfinite(w) or w <= 0 for w in harmonics) or len(set(harmonics)) != len(harmonics):
            raise ConfigError(f"harmonics must be distinct positive frequencies, got {self.harmonics!r}")
        object.__setattr__(self, "harmonics", harmonics)

    # ------------------------------------------------------------------ layout
    @property
    def mlp(self) -> BatchedMLP:
        cached = self.__dict__.get("_mlp")
        if cached is None:
            cached = BatchedMLP(self.hidden, self.activation)
            object.__setattr__(self, "_mlp", cached)  # a layout only: safe to share
        return cached

    @property
    def exact_symmetry(self) -> str:
        return self.symmetry if self.symmetry_mode == "exact" else "none"

    @property
    def uses_mirror(self) -> bool:
        """Exact parity evaluates the network at u and -u together (callers may precompute both)."""
        return self.exact_symmetry != "none"

    @property
    def has_linear(self) -> bool:
        return self.linear_term and self.exact_symmetry != "even"

    @property
    def poly_powers(self) -> tuple[int, ...]:
        """The extra powers that survive the exact parity."""
        sym = self.exact_symmetry
        return tuple(k for k in self.powers if sym == "none" or (k % 2 == 1) == (sym == "odd"))

    @property
    def harmonic_columns(self) -> tuple[tuple[str, float], ...]:
        """``("sin", w)`` and ``("cos", w)`` pairs of the harmonic terms that survive the exact parity."""
        sym = self.exact_symmetry
        kinds = {"none": ("sin", "cos"), "odd": ("sin",), "even": ("cos",)}[sym]
        return tuple((k, w) for w in self.harmonics for k in kinds)

    def harmonic_values(self, u: torch.Tensor, derivative: bool = False) -> list:
        """The harmonic columns at ``u`` (their derivatives in ``u`` with ``derivative``)."""
        if derivative:
            return [w * torch.cos(w * u) if k == "sin" else -w * torch.sin(w * u) for k, w in self.harmonic_columns]
        return [torch.sin(w * u) if k == "sin" else torch.cos(w * u) for k, w in self.harmonic_columns]

    @property
    def n_params(self) -> int:
        return (self.mlp.n_params + int(self.has_linear) + len(self.poly_powers) + len(self.harmonic_columns)
                + 2 * int(self.jump))

    @property
    def pinned_at_zero(self) -> bool:
        """True when the parametrisation forces f(0) = 0 (exact odd symmetry)."""
        return self.exact_symmetry == "odd"

    def slices(self) -> dict[str, slice]:
        n = self.mlp.n_params
        out = {"mlp": slice(0, n)}
        if self.has_linear:
            out["linear"] = slice(n, n + 1)
            n += 1
        if self.poly_powers:
            out["poly"] = slice(n, n + len(self.poly_powers))
            n += len(self.poly_powers)
        if self.harmonic_columns:
            out["harmonic"] = slice(n, n + len(self.harmonic_columns))
            n += len(self.harmonic_columns)
        if self.jump:
            out["jump_height"] = slice(n, n + 1)
            out["jump_log_eps"] = slice(n + 1, n + 2)
        return out

    def init(self, K: int, generator: torch.Generator, dtype=torch.float64) -> torch.Tensor:
        """Initial weights ``(K, n_params)``: PyTorch's default for the network, except that an
        exact even curve's input weights are moved away from 0 (module docstring); the same
        random draws either way, so a seed gives the same start for every other curve."""
        mlp_part = self.mlp.init(K, generator, dtype)
        if self.exact_symmetry == "even":
            lo, hi = EVEN_INPUT_WEIGHTS
            n_in = self.hidden[0]  # first layer: fan_in 1, so its weights are the first n_in entries
            w = mlp_part[:, :n_in]  # U(-1, 1): keep the sign, map |w| onto [lo, hi]
            mlp_part[:, :n_in] = torch.sign(w) * (lo + (hi - lo) * w.abs())
        parts = [mlp_part]
        if self.has_linear:
            parts.append(torch.zeros(K, 1, dtype=dtype))
        if self.poly_powers:
            parts.append(torch.zeros(K, len(self.poly_powers), dtype=dtype))
        if self.harmonic_columns:
            parts.append(torch.zeros(K, len(self.harmonic_columns), dtype=dtype))
        if self.jump:
            parts.append(torch.zeros(K, 1, dtype=dtype))
            parts.append(torch.full((K, 1), math.log(0.01), dtype=dtype))
        return torch.cat(parts, dim=1)

    def output_layer(self, theta: torch.Tensor, u: torch.Tensor, u_both: torch.Tensor | None = None):
        """The columns through which the network's output layer enters the curve, and where its
        weights sit in a curve's parameters.

        The curve is linear in the last layer's weights and bias, so least squares on these
        columns (``(K, N, n_last + 1)``, the symmetrised last hidden activations and ones) fits
        that layer for the current hidden layers.

        Returns
        -------
        columns : torch.Tensor
        where : slice
        """
        mlp = self.mlp
        n_last = self.hidden[-1] + 1
        _, J, _ = self._network_jacobian(theta, u, u_both)
        return J[:, :, mlp.n_params - n_last:], slice(mlp.n_params - n_last, mlp.n_params)

    def _network_jacobian(self, theta, u, u_both=None, derivative: bool = False):
        """The (symmetrised) network part: values ``(K, N)``, Jacobian ``(K, N, n_mlp)``, ``u`` as
        ``(K, N)`` and, with ``derivative``, the network's derivative in ``u``."""
        th = theta[:, self.slices()["mlp"]]
        if u.dim() == 1:
            u = u.unsqueeze(0).expand(theta.shape[0], -1)
        sym = self.exact_symmetry
        if sym == "none":
            out = self.mlp.forward_jacobian(th, u, with_input_derivative=derivative)
            return (out[0], out[1], u, out[2]) if derivative else (out[0], out[1], u)
        n = u.shape[1]
        out = self.mlp.forward_jacobian(th, torch.cat([u, -u], dim=1) if u_both is None else u_both,
                                        with_input_derivative=derivative)
        yb, Jb = out[0], out[1]
        s = -1.0 if sym == "odd" else 1.0
        res: tuple = (0.5 * (yb[:, :n] + s * yb[:, n:]), 0.5 * (Jb[:, :n] + s * Jb[:, n:]), u)
        if derivative:  # d/du of h(-u) is -h'(-u)
            db = out[2]
            res = (*res, 0.5 * (db[:, :n] - s * db[:, n:]))
        return res

    # ------------------------------------------------------------------ evaluation
    def evaluate(self, theta: torch.Tensor, u: torch.Tensor, u_both: torch.Tensor | None = None) -> torch.Tensor:
        """Curve values ``(K, N)`` at scaled arguments ``u`` (``(K, N)`` or ``(N,)``).

        ``u_both`` may pass ``cat([u, -u])`` precomputed (training evaluates the same inputs often).
        """
        sl = self.slices()
        mlp = self.mlp
        th = theta[:, sl["mlp"]]
        if u.dim() == 1:
            u = u.unsqueeze(0).expand(theta.shape[0], -1)
        sym = self.exact_symmetry
        if sym == "none":
            y = mlp.forward(th, u)
        else:
            both = mlp.forward(th, torch.cat([u, -u], dim=1) if u_both is None else u_both)
            n = u.shape[1]
            y = 0.5 * (both[:, :n] - both[:, n:]) if sym == "odd" else 0.5 * (both[:, :n] + both[:, n:])
        if self.has_linear:
            y = y + theta[:, sl["linear"]] * u
        if self.poly_powers:
            c = theta[:, sl["poly"]]
            for j, k in enumerate(self.poly_powers):
                y = y + c[:, j:j + 1] * u**k
        if self.harmonic_columns:
            a = theta[:, sl["harmonic"]]
            for j, col in enumerate(self.harmonic_values(u)):
                y = y + a[:, j:j + 1] * col
        if self.jump:
            mu = theta[:, sl["jump_height"]]
            eps = torch.exp(jump_log_eps(theta[:, sl["jump_log_eps"]]))
            y = y + mu * torch.tanh(u / eps)
        return y

    def evaluator(self, theta: torch.Tensor):
        """``u -> evaluate(theta, u)`` for fixed ``theta`` (``u``: ``(K, N)``), with the per-call work
        done once (output error's free run evaluates the same weights at every integration stage):
        the weights unpacked and, under an exact parity, the network at ``u`` and ``-u`` laid out as
        one network of twice the width whose output layer forms ``(h(u) -+ h(-u)) / 2``."""
        sl = self.slices()
        mlp = self.mlp
        layers = mlp._unpack(theta[:, sl["mlp"]])
        if self.exact_symmetry != "none":
            layers = _mirrored(layers, self.exact_symmetry)
        lin = theta[:, sl["linear"]] if self.has_linear else None
        poly = [(theta[:, sl["poly"]][:, j:j + 1], k) for j, k in enumerate(self.poly_powers)]
        harm = theta[:, sl["harmonic"]] if self.harmonic_columns else None
        mu = eps = None
        if self.jump:
            mu = theta[:, sl["jump_height"]]
            eps = torch.exp(jump_log_eps(theta[:, sl["jump_log_eps"]]))

        def f(u):
            y = mlp.forward_unpacked(layers, u)
            if lin is not None:
                y = torch.addcmul(y, lin, u)
            for c, k in poly:
                y = torch.addcmul(y, c, u**k)
            if harm is not None:
                for j, col in enumerate(self.harmonic_values(u)):
                    y = torch.addcmul(y, harm[:, j:j + 1], col)
            if mu is not None:
                y = torch.addcmul(y, mu, torch.tanh(u / eps))
            return y

        return f

    def evaluate_jacobian(self, theta: torch.Tensor, u: torch.Tensor, u_both: torch.Tensor | None = None):
        """Values ``(K, N)`` and Jacobian ``(K, N, n_params)``."""
        return self._evaluate_jacobian(theta, u, u_both, derivative=False)[:2]

    def evaluate_all(self, theta: torch.Tensor, u: torch.Tensor):
        """Values ``(K, N)``, Jacobian ``(K, N, n_params)`` and the derivative ``d f / d u`` ``(K, N)``
        (what output-error training needs at every integration stage)."""
        return self._evaluate_jacobian(theta, u, None, derivative=True)

    def decay_groups(self) -> list[tuple[slice, str]]:
        """MacKay's groups of the network: each layer's weights and its biases (linear, jump parts free)."""
        out, start = [], self.slices()["mlp"].start
        for layer, (fan_in, fan_out) in enumerate(self.mlp.layers, start=1):
            for kind, size in (("weights", fan_in * fan_out), ("biases", fan_out)):
                out.append((slice(start, start + size), f"layer {layer} {kind}"))
                start += size
        if self.poly_powers and self.decay_powers:
            out.append((self.slices()["poly"], "polynomial terms"))
        return out

    def linear_parts(self, theta: torch.Tensor, u: torch.Tensor, u_both: torch.Tensor | None = None) -> list:
        """Parameters that enter linearly and their columns ``(K, N)``, for least-squares starts:
        the linear part, the jump height (at the current width) and, for exact even curves, the
        output layer (flagged ``True``: guarded by a small ridge, see the module docstring)."""
        sl = self.slices()
        out = []
        if self.exact_symmetry == "even":
            feats, where = self.output_layer(theta, u, u_both)
            out += [(where.start + j, feats[:, :, j], True) for j in range(feats.shape[2])]
        if u.dim() == 1:
            u = u.unsqueeze(0).expand(theta.shape[0], -1)
        if "linear" in sl:
            out.append((sl["linear"].start, u, False))
        for j, k in enumerate(self.poly_powers):
            out.append((sl["poly"].start + j, u**k, False))
        for j, col in enumerate(self.harmonic_values(u)):
            out.append((sl["harmonic"].start + j, col, False))
        if self.jump:
            eps = torch.exp(jump_log_eps(theta[:, sl["jump_log_eps"]]))
            out.append((sl["jump_height"].start, torch.tanh(u / eps), False))
        return out

    def _evaluate_jacobian(self, theta, u, u_both, derivative: bool):
        sl = self.slices()
        if derivative:
            y, J, u, d = self._network_jacobian(theta, u, u_both, derivative=True)
        else:
            y, J, u = self._network_jacobian(theta, u, u_both)
            d = None
        cols = [J]
        if self.has_linear:
            y = y + theta[:, sl["linear"]] * u
            cols.append(u.unsqueeze(-1))
        if self.poly_powers:
            c = theta[:, sl["poly"]]
            for j, k in enumerate(self.poly_powers):
                y = y + c[:, j:j + 1] * u**k
                cols.append((u**k).unsqueeze(-1))
                if d is not None:
                    d = d + c[:, j:j + 1] * k * u ** (k - 1)
        if self.harmonic_columns:
            a = theta[:, sl["harmonic"]]
            for j, col in enumerate(self.harmonic_values(u)):
                y = y + a[:, j:j + 1] * col
                cols.append(col.unsqueeze(-1))
            if d is not None:
                for j, col in enumerate(self.harmonic_values(u, derivative=True)):
                    d = d + a[:, j:j + 1] * col
        if self.jump:
            mu = theta[:, sl["jump_height"]]
            raw = theta[:, sl["jump_log_eps"]]
            eps = torch.exp(jump_log_eps(raw))
            th_ = torch.tanh(u / eps)
            y = y + mu * th_
            cols.append(th_.unsqueeze(-1))
            # d/d(log eps) of mu*tanh(u/eps) = -mu * sech^2(u/eps) * u/eps, times d(log eps)/d(raw)
            cols.append((-mu * (1 - th_ * th_) * u / eps * _dlog_eps(raw)).unsqueeze(-1))
            if d is not None:
                d = d + mu * (1 - th_ * th_) / eps
        if d is not None and self.has_linear:
            d = d + theta[:, sl["linear"]]
        return y, torch.cat(cols, dim=2), d


def _mirrored(layers, sym: str):
    """The layers of ``u -> (h(u) -+ h(-u)) / 2`` as one network: the first layer sees ``u`` and
    ``-u`` side by side, the hidden layers act block-diagonally, and the output layer takes the half
    sum (even) or half difference (odd; the bias cancels)."""
    (W1, b1), *hidden, (Wn, bn) = layers
    out = [(torch.cat([W1, -W1], dim=2), torch.cat([b1, b1], dim=2))]
    for W, b in hidden:
        Z = torch.zeros_like(W)
        out.append((torch.cat([torch.cat([W, Z], dim=2), torch.cat([Z, W], dim=2)], dim=1), torch.cat([b, b], dim=2)))
    if sym == "odd":
        out.append((0.5 * torch.cat([Wn, -Wn], dim=1), torch.zeros_like(bn)))
    else:
        out.append((0.5 * torch.cat([Wn, Wn], dim=1), bn))
    return out
