"""The output-error problem: multiple shooting through a fixed-step RK4 of the template, with exact
forward sensitivities, in the form the batched Levenberg-Marquardt trainer takes.

For each model row (a record's ensemble member) and each segment of the record, the template's ODE
(:class:`~charcurves.templates.ForwardModel`) is integrated by classical RK4 over the segment from
its own initial state, driven by the record's input (linear / zero-order / band-limited hold, a
few RK4 steps per sample), and the simulated positions are compared with the measured ones. The
derivatives of the simulated states with respect to every parameter (curves, scalars, constants,
gain) and to the segment's initial state are exact for the discrete RK4 map, so Levenberg-Marquardt
gets the exact Jacobian; :mod:`._shooting_ode` computes them from the stages of the free run (a
vectorised linearisation and one small matrix product per step). The last two free runs are
remembered: the Jacobian at an accepted trial point costs no second run. Consecutive segments can
be tied by weighted continuity residuals.

Parameters per row: ``[curve blocks | scalars | offsets | gain | initial states (segment-major)]``.
"""

from __future__ import annotations

import math
import torch

from ..train import LeastSquaresProblem
from ._shooting_ode import ShootingODE, curve_evaluator

__all__ = ["ShootingProblem", "CurveBlock"]


class CurveBlock:
    """One curve in the shooting problem: ``F = shift + out * param((u - center) / half)``.

    ``center``, ``half``, ``out`` and ``shift`` are ``(B, 1)`` tensors (records differ in scale);
    ``frozen`` lists parameter indices (within the curve) that stay fixed (a jump's width).
    """

    def __init__(self, name, param, center, half, out, shift, frozen=()):
        self.name, self.param = name, param
        self.center, self.half, self.out, self.shift = center, half, out, shift
        self.frozen = tuple(frozen)
        self.n_params = int(param.n_params)
        # the free run skips the identity parts of the argument map and the output scale
        self._centred = not bool((center == 0).all())
        self._scaled_in = not bool((half == 1).all())
        self._scaled_out = not bool((out == 1).all())
        self._shifted = not bool((shift == 0).all())

    def evaluator(self, theta):
        """``u -> shift + out * param((u - center) / half)`` at fixed parameters ``theta`` (``(B, n)``,
        this curve's columns): the free run's per-stage values. A curve without an output scale
        whose basis has a constant monomial (a polynomial) carries its shift in that coefficient,
        which saves one tensor operation per RK4 stage."""
        k = _constant_column(self.param) if self._shifted and not self._scaled_out else None
        if k is None:
            ev = curve_evaluator(self.param, theta)
            return lambda u: self.value(ev, u)
        theta = theta.clone()
        theta[:, k] += self.shift[:, 0]
        ev = curve_evaluator(self.param, theta)
        centred, scaled = self._centred, self._scaled_in
        center, half = self.center, self.half

        def f(u):
            z = u - center if centred else u
            return ev(z / half if scaled else z)

        return f

    def value(self, evaluate, u):
        """``shift + out * evaluate((u - center) / half)`` (``evaluate``: the parametrisation at
        fixed parameters, :func:`~._shooting_ode.curve_evaluator`)."""
        z = u - self.center if self._centred else u
        f = evaluate(z / self.half if self._scaled_in else z)
        if self._scaled_out:
            f = torch.addcmul(self.shift, self.out, f) if self._shifted else self.out * f
        elif self._shifted:
            f = f + self.shift
        return f


def _constant_column(param) -> int | None:
    """The column of a parametrisation whose basis function is the constant monomial, or None
    (networks, bases without a constant, other than plain monomials)."""
    powers_of = getattr(getattr(param, "curve", None), "monomial_powers", None)
    powers = powers_of() if callable(powers_of) else None
    return list(powers).index(0) if powers is not None and 0 in powers else None


class ShootingProblem(ShootingODE, LeastSquaresProblem):
    """See the module docstring.

    Parameters
    ----------
    forward : ForwardModel
    blocks : list of CurveBlock
        In the order of ``forward.template.curve_names``.
    scalars, offsets : list
        Names of the template's unknown scalars and the equations (0-based) with a free constant.
    free_gain : bool
    gain : float
        The fixed gain when it is not free.
    inputs : dict
        Force name -> three tensors ``(steps, S)`` of the stage inputs (start, middle, end).
    times : tuple of three tensors ``(steps, S)``
        The stage times.
    measured : tensor ``(S, L, O)``
        Measured positions of each segment (O = number of states).
    out_index : list of int
        Layout entries of the positions.
    scales : tensor ``(D,)``
        Typical size of each layout entry (continuity residuals are divided by it).
    dt, substeps, continuity, contiguous
        Sample step, RK4 steps per sample, weight of the continuity residuals, and which segment
        pairs ``(s, s + 1)`` abut (continuity applies only there).
    """

    def __init__(self, forward, blocks, scalars, offsets, free_gain, gain, inputs, times, measured, out_index,
                 scales, dt, substeps, continuity, contiguous, *, weight_decay=0.0, bayesian=False,
                 decay_groups="shared", dtype=torch.float64):
        self.forward = forward
        self.blocks = blocks
        self.scalars, self.offsets = list(scalars), list(offsets)
        self.free_gain, self.gain = bool(free_gain), float(gain)
        self.inputs, self.times = inputs, times
        self.measured = measured
        self.out_index = list(out_index)
        self.S, self.L, self.O = measured.shape
        self.D = forward.n_state
        self.scales = scales
        self.dt, self.substeps = float(dt), int(substeps)
        self.continuity = float(continuity)
        self.contiguous = contiguous  # (S - 1,) bool tensor
        self.dtype = dtype
        o = 0
        self.block_offsets = []
        for b in blocks:
            self.block_offsets.append(o)
            o += b.n_params
        self.scalar_index = {s: o + i for i, s in enumerate(self.scalars)}
        o += len(self.scalars)
        self.offset_index = {e: o + i for i, e in enumerate(self.offsets)}
        o += len(self.offsets)
        self.gain_index = o if self.free_gain else None
        o += int(self.free_gain)
        self.n_shared = o
        self.n_params = o + self.S * self.D
        self.n_data = self.S * self.L * self.O
        self.n_cont = int(self.contiguous.sum()) * self.D if self.continuity > 0 else 0
        B = blocks[0].center.shape[0] if blocks else 1
        self.y = measured.new_zeros(B, self.n_data)  # reference tensor (rows, device, dtype)
        self.n_used = torch.full((B,), float(self.n_data), dtype=dtype)
        self.gamma = None
        self.weight_decay = weight_decay
        self.bayesian = bayesian
        # coefficients of physical size (closed forms, polynomials): the evidence starts from a decay
        # scaled to them (see _evidence.initial_decay)
        self.scaled_initial_decay = True
        self.decay_groups = decay_groups
        self._setup_decay([(self.block_offsets[i], b.param) for i, b in enumerate(blocks)], self.n_params)
        frozen = torch.zeros(self.n_params, dtype=torch.bool)
        for i, b in enumerate(blocks):
            for j in b.frozen:
                frozen[self.block_offsets[i] + j] = True
        self.frozen = frozen if bool(frozen.any()) else None
        self.A_inv_list = None if forward.divides else [[float(a) for a in row] for row in forward.A_inv]
        self._compiled = None
        self._memo: list = []
        self._out_w = 1.0 / math.sqrt(self.n_data)

    @property
    def K(self) -> int:
        return self.y.shape[0]

    def subset(self, rows: slice) -> ShootingProblem:
        import copy

        sub = copy.copy(self)
        sub._compiled = None
        sub._memo = []
        sub.blocks = [CurveBlock(b.name, b.param, b.center[rows], b.half[rows], b.out[rows], b.shift[rows], b.frozen)
                      for b in self.blocks]
        sub.y = self.y[rows]
        sub.n_used = self.n_used[rows]
        wd = self.weight_decay
        sub.weight_decay = wd[rows] if torch.is_tensor(wd) and wd.dim() else wd
        sub.gamma = None
        sub.set_weight_decay(sub.weight_decay)
        return sub

    # ------------------------------------------------------------------ simulation
    def _run(self, theta):
        """The free run of ``theta`` (:meth:`ShootingODE._free_run`), remembered for the last two
        parameter sets: Levenberg-Marquardt asks for the residuals at a trial point and then for the
        Jacobian at the accepted rows, which are each either that trial's or the previous point's."""
        if theta.requires_grad:
            return self._free_run(theta)
        for key, out in self._memo:
            if key.shape == theta.shape and torch.equal(key, theta):
                return out
        if len(self._memo) == 2 and theta.shape == self._memo[0][0].shape == self._memo[1][0].shape:
            (ka, a), (kb, b) = self._memo
            in_a, in_b = (ka == theta).all(dim=1), (kb == theta).all(dim=1)
            if bool((in_a | in_b).all()):  # each row is one of the two runs: take it from there
                rows = in_a
                X = torch.where(rows.view(-1, 1, 1, 1), a[0], b[0])
                y_end = torch.where(rows.view(-1, 1, 1), a[1], b[1])
                kept = [[torch.where(rows.view(-1, 1), pa, pb) for pa, pb in zip(la, lb)] for la, lb in zip(a[2], b[2])]
                out = (X, y_end, kept)
                self._remember(theta, out)
                return out
        out = self._free_run(theta)
        self._remember(theta, out)
        return out

    def _remember(self, theta, out) -> None:
        self._memo = [*self._memo[-1:], (theta.detach().clone(), out)]

    def simulate(self, theta, need_jac: bool = True):
        """Positions ``(B, S, L, O)``, end states ``(B, S, D)`` and, with ``need_jac``, their
        sensitivities to the shared parameters and to each segment's initial state."""
        X, y_end, kept = self._run(theta)
        if not need_jac:
            return X, y_end, None
        return X, y_end, self._sensitivities(theta, kept)

    # ------------------------------------------------------------------ residuals
    def _residual_parts(self, theta, X, y_end):
        B = theta.shape[0]
        scale = self.scales.to(theta.dtype)
        r = ((X - self.measured.unsqueeze(0)) / scale[self.out_index]).reshape(B, -1) * self._out_w
        parts = [r]
        if self.n_cont:
            y0 = theta[:, self.n_shared:].reshape(B, self.S, self.D)
            gap = (y_end[:, :-1] - y0[:, 1:]) / scale  # (B, S-1, D)
            parts.append(gap[:, self.contiguous].reshape(B, -1) * (self.continuity * self._out_w))
        if self.decay_index is not None:
            parts.append(self._sqrt_wd * theta[:, self.decay_index])
        return torch.cat(parts, dim=1)

    def residuals(self, theta):
        X, y_end, _ = self.simulate(theta, need_jac=False)
        r = self._residual_parts(theta, X, y_end)
        return torch.nan_to_num(r, nan=1e3, posinf=1e3, neginf=-1e3)

    def loss(self, theta):
        return self.residuals(theta).pow(2).sum(dim=1)

    def residuals_jacobian(self, theta):
        B = theta.shape[0]
        S, L, O, D, P = self.S, self.L, self.O, self.D, self.n_shared
        X, y_end, (SXt, SXy, St_end, Sy_end) = self.simulate(theta, need_jac=True)
        r = self._residual_parts(theta, X, y_end)
        scale = self.scales.to(theta.dtype)
        w = self._out_w / scale[self.out_index]  # (O,)
        n_rows = r.shape[1]
        J = theta.new_zeros(B, n_rows, self.n_params)
        Jd = J[:, :self.n_data].view(B, S, L, O, self.n_params)
        Jd[..., :P] = SXt * w.view(1, 1, 1, O, 1)
        # each segment's own initial state: the diagonal of (segment of the row, segment of the column)
        own = Jd[..., P:].view(B, S, L, O, S, D).diagonal(dim1=1, dim2=4)  # (B, L, O, D, S), a view
        own.copy_((SXy * w.view(1, 1, 1, O, 1)).permute(0, 2, 3, 4, 1))
        row = self.n_data
        if self.n_cont:
            # per contiguous pair (s, s + 1) and state entry d: d(end of s - start of s + 1) / scale[d]
            c = self.continuity * self._out_w
            pairs = torch.nonzero(self.contiguous).flatten()
            n_pairs = pairs.numel()
            cs = (c / scale).view(1, 1, D, 1)
            Jc = J[:, row:row + n_pairs * D]
            Jc[..., :P] = (St_end[:, pairs] * cs).reshape(B, n_pairs * D, P)
            Ji = Jc[..., P:].view(B, n_pairs, D, S, D)
            at = torch.arange(n_pairs)
            Ji[:, at, :, pairs, :] = (Sy_end[:, pairs] * cs).transpose(0, 1)  # (pairs, B, D, D)
            dd = torch.arange(D)
            Ji[:, at.view(-1, 1), dd.view(1, -1), (pairs + 1).view(-1, 1), dd.view(1, -1)] = -(c / scale)
            row += n_pairs * D
        if self.decay_index is not None:
            m = self.decay_index.numel()
            J[:, row + torch.arange(m), self.decay_index] = (
                self._sqrt_wd.expand(B, m) if self._sqrt_wd.dim() else self._sqrt_wd)
        if self.frozen is not None:
            J[:, :, self.frozen] = 0.0
        bad = ~torch.isfinite(r)
        if bool(bad.any()):
            r = torch.nan_to_num(r, nan=1e3, posinf=1e3, neginf=-1e3)
            J = torch.nan_to_num(J, nan=0.0, posinf=0.0, neginf=0.0)
        return r, J

