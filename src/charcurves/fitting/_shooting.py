"""The output-error problem: multiple shooting through a fixed-step RK4 of the template, with exact
forward sensitivities, in the form the batched Levenberg-Marquardt trainer takes.

For each model row (a record's ensemble member) and each segment of the record, the template's ODE
(:class:`~charcurves.templates.ForwardModel`) is integrated by classical RK4 over the segment from
its own initial state, driven by the record's input (linear / zero-order / band-limited hold, a
few RK4 steps per sample), and the simulated positions are compared with the measured ones.
Alongside the state, its derivatives with respect to every parameter (curves, scalars, constants,
gain) and to the segment's initial state are integrated exactly for the discrete RK4 map (the
variational equations, stage by stage), so Levenberg-Marquardt gets the exact Jacobian from one
pass. Consecutive segments can be tied by weighted continuity residuals.

Parameters per row: ``[curve blocks | scalars | offsets | gain | initial states (segment-major)]``.
"""

from __future__ import annotations

import math

import torch

from ._problem import LeastSquaresProblem

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


class ShootingProblem(LeastSquaresProblem):
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
        self.decay_groups = decay_groups
        self._setup_decay([(self.block_offsets[i], b.param) for i, b in enumerate(blocks)], self.n_params)
        frozen = torch.zeros(self.n_params, dtype=torch.bool)
        for i, b in enumerate(blocks):
            for j in b.frozen:
                frozen[self.block_offsets[i] + j] = True
        self.frozen = frozen if bool(frozen.any()) else None
        self.A_inv = torch.as_tensor(forward.A_inv, dtype=dtype)
        self._out_w = 1.0 / math.sqrt(self.n_data)

    @property
    def K(self) -> int:
        return self.y.shape[0]

    def subset(self, rows: slice) -> ShootingProblem:
        import copy

        sub = copy.copy(self)
        sub.blocks = [CurveBlock(b.name, b.param, b.center[rows], b.half[rows], b.out[rows], b.shift[rows], b.frozen)
                      for b in self.blocks]
        sub.y = self.y[rows]
        sub.n_used = self.n_used[rows]
        wd = self.weight_decay
        sub.weight_decay = wd[rows] if torch.is_tensor(wd) and wd.dim() else wd
        sub.gamma = None
        sub.set_weight_decay(sub.weight_decay)
        return sub

    # ------------------------------------------------------------------ the ODE at one stage
    def _rhs(self, theta, y, stage_vals, need_jac: bool):
        """``dy (B,S,D)`` and, with ``need_jac``, ``Jy (B,S,D,D)``, ``Jt (B,S,D,P_shared)``."""
        fm = self.forward
        B, S, D = y.shape
        like = y[..., 0]
        vals = dict(stage_vals)
        for i, name in enumerate(fm.layout):
            vals[name] = y[..., i]
        E = len(fm.equations)
        curve_vals = {}
        for bi, blk in enumerate(self.blocks):
            sig = fm.curves[blk.name]
            u = sig.value(vals, like)
            th = theta[:, self.block_offsets[bi]:self.block_offsets[bi] + blk.n_params]
            z = (u - blk.center) / blk.half
            if need_jac:
                f, J, d = blk.param.evaluate_all(th, z)
                curve_vals[blk.name] = (blk.shift + blk.out * f, (blk.out / blk.half) * d, blk.out.unsqueeze(-1) * J,
                                        sig.grad(vals, like), bi)
            else:
                curve_vals[blk.name] = (blk.shift + blk.out * blk.param.evaluate(th, z), None, None, None, bi)
        g = theta[:, self.gain_index:self.gain_index + 1] if self.free_gain else self.gain
        r0 = []
        dr_y = [] if need_jac else None
        dr_t = [] if need_jac else None
        for e, eq in enumerate(fm.equations):
            inp = eq["input"].value(vals, like)
            r = eq["known0"].value(vals, like) - g * inp
            if need_jac:
                ry = like.new_zeros(B, S, D)
                rt = like.new_zeros(B, S, self.n_shared)
                _add_grad(ry, eq["known0"].grad(vals, like), 1.0)
                _add_grad(ry, eq["input"].grad(vals, like), -g)
                if self.free_gain:
                    rt[..., self.gain_index] = -inp
            for name, msig in eq["mult"].items():
                Fv, dF, JF, du, bi = curve_vals[name]
                m = msig.value(vals, like)
                r = r + m * Fv
                if need_jac:
                    _add_grad(ry, msig.grad(vals, like), Fv)
                    _add_grad(ry, du, m * dF)
                    o = self.block_offsets[bi]
                    rt[..., o:o + self.blocks[bi].n_params] += m.unsqueeze(-1) * JF
            for sname, ssig in eq["scalars"].items():
                j = self.scalar_index[sname]
                a = theta[:, j:j + 1]
                s = ssig.value(vals, like)
                r = r + a * s
                if need_jac:
                    _add_grad(ry, ssig.grad(vals, like), a)
                    rt[..., j] += s
            if e in self.offset_index:
                j = self.offset_index[e]
                r = r + theta[:, j:j + 1]
                if need_jac:
                    rt[..., j] += 1.0
            r0.append(r)
            if need_jac:
                dr_y.append(ry)
                dr_t.append(rt)
        R0 = torch.stack(r0, dim=-1)  # (B, S, E)
        top = -(R0 @ self.A_inv.T)  # (B, S, U)
        dy = torch.empty_like(y)
        for i in range(D):
            j = fm.derivative_of(i)
            dy[..., i] = y[..., j] if j is not None else top[..., fm.top_index(i)]
        if not need_jac:
            return dy, None, None
        Ry = torch.stack(dr_y, dim=-2)  # (B, S, E, D)
        Rt = torch.stack(dr_t, dim=-2)  # (B, S, E, P)
        Ty = -torch.einsum("ue,bsed->bsud", self.A_inv, Ry)
        Tt = -torch.einsum("ue,bsep->bsup", self.A_inv, Rt)
        Jy = like.new_zeros(B, S, D, D)
        Jt = like.new_zeros(B, S, D, self.n_shared)
        for i in range(D):
            j = fm.derivative_of(i)
            if j is not None:
                Jy[..., i, j] = 1.0
            else:
                Jy[..., i, :] = Ty[..., fm.top_index(i), :]
                Jt[..., i, :] = Tt[..., fm.top_index(i), :]
        return dy, Jy, Jt

    def _stage(self, k: int, which: int) -> dict:
        out = {"t": self.times[which][k]}
        for name, arrs in self.inputs.items():
            out[name] = arrs[which][k]
        return out

    # ------------------------------------------------------------------ simulation
    def simulate(self, theta, need_jac: bool = True):
        """Positions ``(B, S, L, O)``, end states ``(B, S, D)`` and, with ``need_jac``, their
        sensitivities to the shared parameters and to each segment's initial state."""
        B = theta.shape[0]
        S, D, P = self.S, self.D, self.n_shared
        y = theta[:, P:].reshape(B, S, D)
        h = self.dt / self.substeps
        outs = [y[..., self.out_index]]
        if need_jac:
            St = y.new_zeros(B, S, D, P)
            Sy = torch.eye(D, dtype=y.dtype).expand(B, S, D, D).clone()
            out_t, out_y = [St[..., self.out_index, :]], [Sy[..., self.out_index, :]]
        steps = (self.L - 1) * self.substeps
        for k in range(steps):
            stages = (self._stage(k, 0), self._stage(k, 1), self._stage(k, 1), self._stage(k, 2))
            acc = 0.0
            acc_t = acc_y = 0.0
            for st, (c, w) in enumerate(((0.0, 1.0), (0.5, 2.0), (0.5, 2.0), (1.0, 1.0))):
                if st == 0:
                    ys, St_s, Sy_s = y, (St if need_jac else None), (Sy if need_jac else None)
                else:
                    ys = y + (c * h) * ky
                    if need_jac:
                        St_s = St + (c * h) * kt
                        Sy_s = Sy + (c * h) * kyy
                ky, Jy, Jt = self._rhs(theta, ys, stages[st], need_jac)
                acc = acc + w * ky
                if need_jac:
                    kt = Jy @ St_s + Jt
                    kyy = Jy @ Sy_s
                    acc_t = acc_t + w * kt
                    acc_y = acc_y + w * kyy
            y = y + (h / 6.0) * acc
            if need_jac:
                St = St + (h / 6.0) * acc_t
                Sy = Sy + (h / 6.0) * acc_y
            if (k + 1) % self.substeps == 0:
                outs.append(y[..., self.out_index])
                if need_jac:
                    out_t.append(St[..., self.out_index, :])
                    out_y.append(Sy[..., self.out_index, :])
        X = torch.stack(outs, dim=2)  # (B, S, L, O)
        if not need_jac:
            return X, y, None
        return X, y, (torch.stack(out_t, dim=2), torch.stack(out_y, dim=2), St, Sy)

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
        seg = torch.arange(S)
        for d in range(D):  # each segment's own initial state
            Jd[:, seg, :, :, P + seg * D + d] = (SXy[..., d] * w.view(1, 1, 1, O)).permute(1, 0, 2, 3)
        row = self.n_data
        if self.n_cont:
            c = self.continuity * self._out_w
            for s in torch.nonzero(self.contiguous).flatten().tolist():
                for d in range(D):
                    J[:, row, :P] = St_end[:, s, d, :] * (c / scale[d])
                    J[:, row, P + s * D:P + (s + 1) * D] = Sy_end[:, s, d, :] * (c / scale[d])
                    J[:, row, P + (s + 1) * D + d] -= c / scale[d]
                    row += 1
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


def _add_grad(target, grads: dict, factor) -> None:
    """``target[..., i] += factor * g_i`` for the non-zero partial derivatives ``grads``."""
    for i, g in grads.items():
        target[..., i] += factor * g
