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
from typing import Any

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
        # coefficients of physical size (closed forms, polynomials): the evidence starts from a decay
        # scaled to them (see _train._initial_decay)
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
        self._out_w = 1.0 / math.sqrt(self.n_data)

    @property
    def K(self) -> int:
        return self.y.shape[0]

    def subset(self, rows: slice) -> ShootingProblem:
        import copy

        sub = copy.copy(self)
        sub._compiled = None
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
    def _plan(self):
        """Per curve and equation: what is a plain state, a constant or a forcing column (no Signal
        call needed at run time), and what needs a compiled Signal."""
        if getattr(self, "_compiled", None) is not None:
            return self._compiled
        fm = self.forward
        curves = []
        for bi, blk in enumerate(self.blocks):
            sig = fm.curves[blk.name]
            name = str(sig.expr)
            curves.append((bi, blk, sig, fm.layout.index(name) if name in fm.layout else None))
        eqs = []
        for e, eq in enumerate(fm.equations):
            inp = eq["input"]
            force = str(inp.expr) if str(inp.expr) in self.inputs and not inp._grads else None
            k0 = eq["known0"]
            mult = {n: (m.constant, m) for n, m in eq["mult"].items()}
            eqs.append((e, k0.constant, k0, force, inp, mult, eq["scalars"]))
        self._mult_top = {n: (m.constant, m) for n, m in fm.equations[0]["mult_top"].items()} if fm.divides else {}
        simple = all(c[3] is not None for c in curves) and all(
            q[1] is not None and q[3] is not None and not q[6] and all(m[0] is not None for m in q[5].values())
            for q in eqs) and all(m[0] is not None for m in self._mult_top.values())
        self._compiled = (curves, eqs, simple)
        return self._compiled

    def _rhs(self, theta, y, stage, need_jac: bool):
        """``dy (B,S,D)`` and, with ``need_jac``, for each layout entry its tangent recipe:
        ``("copy", j)`` (its derivative is entry j) or ``("top", {d: coef}, Tt)`` with
        ``d(dy_i) = sum_d coef_d T_d + Tt`` (``Tt``: ``(B,S,P_shared)`` or None)."""
        fm = self.forward
        curves, eqs, simple = self._plan()
        like = y[..., 0]
        vals = None
        if not simple:
            vals = dict(stage)
            for i, name in enumerate(fm.layout):
                vals[name] = y[..., i]
        cv = {}
        for bi, blk, sig, direct in curves:
            u = y[..., direct] if direct is not None else sig.value(vals, like)
            th = theta[:, self.block_offsets[bi]:self.block_offsets[bi] + blk.n_params]
            z = (u - blk.center) / blk.half
            if need_jac:
                f, J, d = blk.param.evaluate_all(th, z)
                du = {direct: 1.0} if direct is not None else sig.grad(vals, like)
                cv[blk.name] = (blk.shift + blk.out * f, (blk.out / blk.half) * d, blk.out.unsqueeze(-1) * J, du, bi)
            else:
                cv[blk.name] = (blk.shift + blk.out * blk.param.evaluate(th, z), None, None, None, bi)
        g = theta[:, self.gain_index:self.gain_index + 1] if self.free_gain else self.gain
        r0, ry_all, rt_all = [], [], []
        for e, k0c, k0, force, inp, mult, scalars in eqs:
            u_in = stage[force] if force is not None else inp.value(vals, like)
            r = (k0c if k0c is not None else k0.value(vals, like)) - g * u_in
            ry: dict = {}
            rt: Any = None  # (B, S, P_shared) when need_jac
            if need_jac:
                rt = like.new_zeros(*like.shape, self.n_shared)
                if k0c is None:
                    _acc(ry, k0.grad(vals, like), 1.0)
                if force is None:
                    _acc(ry, inp.grad(vals, like), -g)
                if self.free_gain:
                    rt[..., self.gain_index] = -u_in
            for name, (mc, msig) in mult.items():
                Fv, dF, JF, du, bi = cv[name]
                m = mc if mc is not None else msig.value(vals, like)
                r = r + (Fv if mc == 1.0 else m * Fv)
                if need_jac:
                    if mc is None:
                        _acc(ry, msig.grad(vals, like), Fv)
                    _acc(ry, du, dF if mc == 1.0 else m * dF)
                    o = self.block_offsets[bi]
                    if mc == 1.0:
                        rt[..., o:o + self.blocks[bi].n_params] += JF
                    else:
                        rt[..., o:o + self.blocks[bi].n_params] += (m.unsqueeze(-1) if torch.is_tensor(m) else m) * JF
            for sname, ssig in scalars.items():
                j = self.scalar_index[sname]
                a = theta[:, j:j + 1]
                sv = ssig.value(vals, like)
                r = r + a * sv
                if need_jac:
                    _acc(ry, ssig.grad(vals, like), a)
                    rt[..., j] += sv
            if e in self.offset_index:
                j = self.offset_index[e]
                r = r + theta[:, j:j + 1]
                if need_jac:
                    rt[..., j] += 1.0
            r0.append(r)
            ry_all.append(ry)
            rt_all.append(rt)
        if self.forward.divides:
            return self._divided(theta, y, cv, r0[0], ry_all[0], rt_all[0], vals, like, need_jac)
        A = self.A_inv_list
        tops = []
        for u in range(len(A)):
            top = None
            for e, a in enumerate(A[u]):
                if a:
                    top = -a * r0[e] if top is None else top - a * r0[e]
            tops.append(top)
        cols = []
        for i in range(self.D):
            j = fm.derivative_of(i)
            cols.append(y[..., j] if j is not None else tops[fm.top_index(i)])
        dy = torch.stack(cols, dim=-1)
        if not need_jac:
            return dy, None
        recipes: list[tuple] = []
        for i in range(self.D):
            j = fm.derivative_of(i)
            if j is not None:
                recipes.append(("copy", j))
                continue
            u = fm.top_index(i)
            coef: dict = {}
            Tt = None
            for e, a in enumerate(A[u]):
                if not a:
                    continue
                _acc(coef, ry_all[e], -a)
                Tt = -a * rt_all[e] if Tt is None else Tt - a * rt_all[e]
            recipes.append(("top", coef, Tt))
        return dy, recipes

    def _divided(self, theta, y, cv, r, ry, rt, vals, like, need_jac):
        """One equation ``r + c top = 0`` with ``c = A + sum_i m_i f_i``: ``top = -r / c``, and its
        tangent ``-(dr + top dc) / c``."""
        fm = self.forward
        c = fm.A[0][0]
        cy: dict = {}
        ct = like.new_zeros(*like.shape, self.n_shared) if need_jac else None
        for name, (mc, msig) in self._mult_top.items():
            Fv, dF, JF, du, bi = cv[name]
            m = mc if mc is not None else msig.value(vals, like)
            c = c + m * Fv
            if need_jac:
                if mc is None:
                    _acc(cy, msig.grad(vals, like), Fv)
                _acc(cy, du, m * dF)
                o = self.block_offsets[bi]
                ct[..., o:o + self.blocks[bi].n_params] += (m.unsqueeze(-1) if torch.is_tensor(m) else m) * JF
        top = -r / c
        cols = [y[..., j] if (j := fm.derivative_of(i)) is not None else top for i in range(self.D)]
        dy = torch.stack(cols, dim=-1)
        if not need_jac:
            return dy, None
        coef: dict = {}
        _acc(coef, ry, -1.0 / c)
        _acc(coef, cy, -top / c)
        Tt = -(rt + top.unsqueeze(-1) * ct) / c.unsqueeze(-1)
        recipes = [("copy", j) if (j := fm.derivative_of(i)) is not None else ("top", coef, Tt)
                   for i in range(self.D)]
        return dy, recipes

    # ------------------------------------------------------------------ simulation
    def simulate(self, theta, need_jac: bool = True):
        """Positions ``(B, S, L, O)``, end states ``(B, S, D)`` and, with ``need_jac``, their
        sensitivities to the shared parameters and to each segment's initial state."""
        B = theta.shape[0]
        S, D, P = self.S, self.D, self.n_shared
        y = theta[:, P:].reshape(B, S, D)
        h = self.dt / self.substeps
        outs = [y[..., self.out_index]]
        T: list = []
        out_t: list = []
        if need_jac:
            # tangent of each layout entry: (B, S, P + D) = [shared parameters | own initial state]
            for d in range(D):
                t = y.new_zeros(B, S, P + D)
                t[..., P + d] = 1.0
                T.append(t)
            out_t.append(torch.stack([T[o] for o in self.out_index], dim=2))
        names = list(self.inputs)
        weights = ((0.0, 1.0), (0.5, 2.0), (0.5, 2.0), (1.0, 1.0))
        for k in range((self.L - 1) * self.substeps):
            st = [{"t": self.times[w][k], **{n: self.inputs[n][w][k] for n in names}} for w in (0, 1, 2)]
            stages = (st[0], st[1], st[1], st[2])
            acc = None
            accT: list = []
            ky: Any = None
            kT: Any = None
            for si, (c, w) in enumerate(weights):
                ys = y if si == 0 else y + (c * h) * ky
                Ts = T if (si == 0 or not need_jac) else [T[d] + (c * h) * kT[d] for d in range(D)]
                ky, recipes = self._rhs(theta, ys, stages[si], need_jac)
                acc = w * ky if acc is None else acc + w * ky
                if need_jac:
                    kT = []
                    for rec in recipes:
                        if rec[0] == "copy":
                            kT.append(Ts[rec[1]])
                            continue
                        _, coef, Tt = rec
                        val = torch.nn.functional.pad(Tt, (0, D)) if Tt is not None else y.new_zeros(B, S, P + D)
                        for d, cf in coef.items():
                            val = val + (cf.unsqueeze(-1) if torch.is_tensor(cf) else cf) * Ts[d]
                        kT.append(val)
                    accT = [w * kT[d] for d in range(D)] if si == 0 else [accT[d] + w * kT[d] for d in range(D)]
            y = y + (h / 6.0) * acc
            if need_jac:
                T = [T[d] + (h / 6.0) * accT[d] for d in range(D)]
            if (k + 1) % self.substeps == 0:
                outs.append(y[..., self.out_index])
                if need_jac:
                    out_t.append(torch.stack([T[o] for o in self.out_index], dim=2))
        X = torch.stack(outs, dim=2)  # (B, S, L, O)
        if not need_jac:
            return X, y, None
        Tall = torch.stack(out_t, dim=2)  # (B, S, L, O, P + D)
        Tend = torch.stack(T, dim=2)  # (B, S, D, P + D)
        return X, y, (Tall[..., :P], Tall[..., P:], Tend[..., :P], Tend[..., P:])

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


def _acc(target: dict, grads: dict, factor) -> None:
    """``target[i] += factor * g_i`` for the non-zero partial derivatives ``grads`` (tensors or floats)."""
    for i, g in grads.items():
        v = factor * g
        target[i] = v if i not in target else target[i] + v
