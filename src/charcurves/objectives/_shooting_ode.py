"""The template's ODE at the RK4 stages of output error: the free run and its exact sensitivities.

:class:`ShootingODE` is the part of :class:`~._shooting.ShootingProblem` that integrates. The
sensitivities are computed in two passes, so that the sequential part stays as short as possible:

1. **The free run** (:meth:`ShootingODE._free_run`): classical RK4 of the state alone, every segment
   and model row at once, through the per-stage values of the curves (each parametrisation's
   ``evaluator(theta)`` when it has one, with its unpacking hoisted out of the loop), keeping the
   state at every stage.
2. **The linearisation** (:meth:`ShootingODE._sensitivities`): the ODE's partial derivatives in the
   state and the parameters at *all* the kept stages in one vectorised evaluation (the time axis
   folded into the batch), combined into each RK4 step's exact derivatives ``Phi = d y_{k+1} / d y_k``
   and ``Psi = d y_{k+1} / d params`` (the chain rule through the four stages), and then the
   sensitivities of every segment to the shared parameters and to its initial state by the linear
   recurrence ``T_{k+1} = Phi_k T_k + [Psi_k | 0]``: one small batched matrix product per step.

Both are the exact derivatives of the discrete RK4 map, as before; only the order of the work changed
(the earlier version propagated the tangents stage by stage alongside the state, with a few hundred
small tensor operations per stage).
"""

from __future__ import annotations

from typing import Any

import torch

__all__ = ["ShootingODE", "curve_evaluator"]

#: Elements of the largest per-stage Jacobian array one linearisation pass builds (the time axis is
#: processed in chunks of steps below it; 2**22 float64 = 32 MiB).
CHUNK_ELEMENTS = 1 << 18


def curve_evaluator(param, theta):
    """``z -> values (K, N)`` of a parametrisation at fixed parameters ``theta`` (``(K, n)``): its own
    ``evaluator`` when it has one (the parameter unpacking done once), else ``param.evaluate``."""
    make = getattr(param, "evaluator", None)
    if make is not None:
        return make(theta)
    return lambda z: param.evaluate(theta, z)


class ShootingODE:
    """The ODE of :class:`~._shooting.ShootingProblem` (module docstring); attributes set there."""

    forward: Any
    blocks: list
    inputs: dict
    times: tuple
    scalar_index: dict
    offset_index: dict
    block_offsets: list
    free_gain: bool
    gain: float
    gain_index: Any  # int when the gain is free
    n_shared: int
    D: int
    S: int
    L: int
    dt: float
    substeps: int
    A_inv_list: list | None
    out_index: list
    _compiled: Any

    # ------------------------------------------------------------------ layout of the template
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
        # each layout entry: (the entry that is its derivative, or None; which top derivative it is)
        deriv = [(fm.derivative_of(i), None if fm.derivative_of(i) is not None else fm.top_index(i))
                 for i in range(self.D)]
        self._compiled = (curves, eqs, simple, deriv)
        return self._compiled

    def _stage_tables(self):
        """The stage inputs, once: per step the three dicts (start, middle, end) of the free run, and
        per name ``(steps, 4, S)`` arrays of the four RK4 stages for the linearisation."""
        cached = getattr(self, "_stages_cache", None)
        if cached is not None:
            return cached
        names = list(self.inputs)
        cols = {"t": self.times, **{n: self.inputs[n] for n in names}}
        n_steps = (self.L - 1) * self.substeps
        per_step = [tuple({n: cols[n][w][k] for n in cols} for w in (0, 1, 2)) for k in range(n_steps)]
        flat = {n: torch.stack([c[0], c[1], c[1], c[2]], dim=1) for n, c in cols.items()}
        self._stages_cache = (per_step, flat)
        return self._stages_cache

    # ------------------------------------------------------------------ the free run (values only)
    def _value_context(self, theta):
        """What every stage of one free run shares: the curves' evaluators and the scalar columns."""
        curves, eqs, simple, deriv = self._plan()
        fns = []
        for bi, blk, sig, direct in curves:
            o = self.block_offsets[bi]
            fns.append((blk.name, blk.evaluator(theta[:, o:o + blk.n_params]), sig, direct))
        g = theta[:, self.gain_index:self.gain_index + 1] if self.free_gain else self.gain
        sc = {s: theta[:, j:j + 1] for s, j in self.scalar_index.items()}
        off = {e: theta[:, j:j + 1] for e, j in self.offset_index.items()}
        return fns, g, sc, off, eqs, simple, deriv

    def _dy(self, ctx, ys: list, stage: dict) -> list:
        """The time derivative of each layout entry (a list of ``(B, S)`` tensors) at the state ``ys``."""
        fns, g, sc, off, eqs, simple, deriv = ctx
        like = ys[0]
        vals = None
        if not simple:
            vals = dict(stage)
            vals.update(zip(self.forward.layout, ys))
        cv = {}
        for name, ev, sig, direct in fns:
            cv[name] = ev(ys[direct] if direct is not None else sig.value(vals, like))
        # each equation as known + curves + ... = g u: the top derivatives solve A top = g u - (the rest)
        rhs = []
        for e, k0c, k0, force, inp, mult, scalars in eqs:
            r: Any = None
            for name, (mc, msig) in mult.items():
                F = cv[name]
                if mc != 1.0:
                    F = (mc if mc is not None else msig.value(vals, like)) * F
                r = F if r is None else r + F
            for sname, ssig in scalars.items():
                r = _plus(r, sc[sname] * ssig.value(vals, like))
            if e in off:
                r = _plus(r, off[e])
            k0v = k0c if k0c is not None else k0.value(vals, like)
            if not (isinstance(k0v, float) and k0v == 0.0):
                r = _plus(r, k0v)
            u_in = stage[force] if force is not None else inp.value(vals, like)
            gu = u_in if isinstance(g, float) and g == 1.0 else g * u_in  # a fixed unit gain: no product
            rhs.append(gu if r is None else gu - r)
        if self.forward.divides:
            c: Any = self.forward.A[0][0]
            for name, (mc, msig) in self._mult_top.items():
                c = c + (mc if mc is not None else msig.value(vals, like)) * cv[name]
            tops = [rhs[0] / c]
        else:
            tops = []
            for row in self.A_inv_list or []:
                top: Any = None
                for e, a in enumerate(row):
                    if a:
                        top = _plus(top, rhs[e] if a == 1.0 else rhs[e] * a)
                tops.append(top)
        out = []
        for j, t in deriv:
            v = ys[j] if j is not None else tops[t]
            out.append(v if v.shape == like.shape else torch.broadcast_to(v, like.shape))
        return out

    def _free_run(self, theta):
        """Positions ``(B, S, L, O)``, end states ``(B, S, D)`` and the state at every stage (per
        layout entry a list of ``(B, S)`` tensors, four per RK4 step, in time order)."""
        B = theta.shape[0]
        S, D, P = self.S, self.D, self.n_shared
        y0 = theta[:, P:].reshape(B, S, D)
        y = [y0[..., d] for d in range(D)]
        h = self.dt / self.substeps
        ctx = self._value_context(theta)
        per_step, _ = self._stage_tables()
        kept: list[list] = [[] for _ in range(D)]
        outs = [[y[o] for o in self.out_index]]
        rng = range(D)
        for k, (s0, s1, s2) in enumerate(per_step):
            k1 = self._dy(ctx, y, s0)
            y2 = [torch.add(y[d], k1[d], alpha=0.5 * h) for d in rng]
            k2 = self._dy(ctx, y2, s1)
            y3 = [torch.add(y[d], k2[d], alpha=0.5 * h) for d in rng]
            k3 = self._dy(ctx, y3, s1)
            y4 = [torch.add(y[d], k3[d], alpha=h) for d in rng]
            k4 = self._dy(ctx, y4, s2)
            for d in rng:
                kept[d] += (y[d], y2[d], y3[d], y4[d])
            acc = [torch.add(torch.add(torch.add(k1[d], k2[d], alpha=2.0), k3[d], alpha=2.0), k4[d]) for d in rng]
            y = [torch.add(y[d], acc[d], alpha=h / 6.0) for d in rng]
            if (k + 1) % self.substeps == 0:
                outs.append([y[o] for o in self.out_index])
        X = torch.stack([torch.stack(col, dim=-1) for col in outs], dim=2)  # (B, S, L, O)
        return X, torch.stack(y, dim=-1), kept

    # ------------------------------------------------------------------ sensitivities
    def _sensitivities(self, theta, kept):
        """Sensitivities of the positions and the end states to the shared parameters and to the
        segment's initial state: ``(B, S, L, O, P)``, ``(B, S, L, O, D)``, ``(B, S, D, P)``, ``(B, S, D, D)``."""
        B = theta.shape[0]
        S, D, P, L = self.S, self.D, self.n_shared, self.L
        n_steps = (L - 1) * self.substeps
        _, flat = self._stage_tables()
        Y = [torch.stack(kept[d], dim=1) for d in range(D)]  # (B, 4 * steps, S)
        Tt = theta.new_zeros(B * S, D, P)
        Ty = torch.eye(D, dtype=theta.dtype, device=theta.device).expand(B * S, D, D).contiguous()
        snaps = [(Tt, Ty)]
        chunk = max(1, CHUNK_ELEMENTS // max(1, B * 4 * S * max(P, 1)))
        for k0 in range(0, n_steps, chunk):
            k1 = min(n_steps, k0 + chunk)
            n = k1 - k0
            yflat = torch.stack([Y[d][:, 4 * k0:4 * k1].reshape(B, -1) for d in range(D)], dim=-1)
            stage = {name: arr[k0:k1].reshape(-1) for name, arr in flat.items()}
            _, recipes = self._rhs(theta, yflat, stage, True)
            Phi, Psi = self._step_maps(recipes, theta, n)
            for j in range(n):
                Tt = torch.baddbmm(Psi[j], Phi[j], Tt)
                Ty = torch.bmm(Phi[j], Ty)
                if (k0 + j + 1) % self.substeps == 0:
                    snaps.append((Tt, Ty))
        SXt = torch.stack([a for a, _ in snaps], dim=0).view(L, B, S, D, P).permute(1, 2, 0, 3, 4)
        SXy = torch.stack([b for _, b in snaps], dim=0).view(L, B, S, D, D).permute(1, 2, 0, 3, 4)
        o = self.out_index
        return SXt[:, :, :, o, :], SXy[:, :, :, o, :], Tt.view(B, S, D, P), Ty.view(B, S, D, D)

    def _step_maps(self, recipes, theta, n):
        """Each RK4 step's exact derivatives from the tangent recipes of its four stages (``_rhs`` at
        ``(B, n * 4 * S)`` stage points): ``Phi = d y_{k+1} / d y_k`` ``(n, B * S, D, D)`` and
        ``Psi = d y_{k+1} / d params`` ``(n, B * S, D, P)``.

        Stage s is evaluated at ``y + c_s h k_{s-1}``, so its tangent is ``K_s = A_s (I + c_s h K_{s-1})
        + G_s`` with ``A_s`` the ODE's derivative in the state (rows of the recipes: a copy of another
        entry, or coefficients) and ``G_s`` in the parameters (``Tt``); the step is ``I + h/6 (K_1 +
        2 K_2 + 2 K_3 + K_4)``. The parameter part is kept row by row as ``(scale, tensor)`` pairs
        (None: zero), so copy rows cost nothing and no zero block is ever formed.
        """
        B = theta.shape[0]
        S, D, P = self.S, self.D, self.n_shared
        h = self.dt / self.substeps
        N = n * 4 * S

        def stage(x, s):  # stage s of a per-point tensor (B, N, ...) -> (B, n, S, ...)
            if not torch.is_tensor(x) or x.dim() == 0:
                return x
            x = torch.broadcast_to(x, (B, N, *x.shape[2:])) if x.dim() < 2 or x.shape[:2] != (B, N) else x
            return x.reshape(B, n, 4, S, *x.shape[2:])[:, :, s]

        eye = torch.eye(D, dtype=theta.dtype, device=theta.device)
        Kt: list = [None] * D  # rows of the previous stage's parameter tangent: (scale, (B, n, S, P)) or None
        Ky: list = [None] * D  # rows of its state tangent: (B, n, S, D) tensors or None (zero)
        psi: list = [None] * D
        phi: list = [None] * D
        for s, (c, w) in enumerate(((0.0, 1.0), (0.5 * h, 2.0), (0.5 * h, 2.0), (h, 1.0))):
            new_t: list = []
            new_y: list = []
            for i, rec in enumerate(recipes):
                if rec[0] == "copy":
                    j = rec[1]
                    new_t.append(None if Kt[j] is None else (c * Kt[j][0], Kt[j][1]))
                    new_y.append(_axpy(eye[j], Ky[j], c))
                    continue
                _, coef, tt = rec
                row = None if tt is None else stage(tt, s)
                ry: torch.Tensor | None = None
                for d, cf in coef.items():
                    cf = stage(cf, s)
                    cft = cf.unsqueeze(-1) if torch.is_tensor(cf) else cf
                    if Kt[d] is not None:
                        a, ten = Kt[d]
                        if row is None:
                            row = ten * (cft * (c * a))
                        elif torch.is_tensor(cft):
                            row = torch.addcmul(row, cft, ten, value=c * a)
                        else:
                            row = row + ten * (cft * c * a)
                    term = cft * _axpy(eye[d], Ky[d], c)
                    ry = term if ry is None else ry + term
                new_t.append(None if row is None else (1.0, row))
                new_y.append(ry)
            Kt, Ky = new_t, new_y
            for i in range(D):
                if Kt[i] is not None:
                    a, ten = Kt[i]
                    psi[i] = ten * (w * a * h / 6.0) if psi[i] is None else torch.add(psi[i], ten, alpha=w * a * h / 6.0)
                if Ky[i] is not None:
                    phi[i] = Ky[i] * (w * h / 6.0) if phi[i] is None else torch.add(phi[i], Ky[i], alpha=w * h / 6.0)
        shape = (B, n, S)
        Psi = torch.stack([p if p is not None else theta.new_zeros(*shape, P) for p in psi], dim=-2)
        Phi = torch.stack([torch.broadcast_to(eye[i] if p is None else eye[i] + p, (*shape, D)) for i, p in
                           enumerate(phi)], dim=-2)
        Psi = Psi.transpose(0, 1).reshape(n, B * S, D, P)
        Phi = Phi.transpose(0, 1).reshape(n, B * S, D, D)
        return Phi, Psi

    # ------------------------------------------------------------------ tangent recipes (any batch)
    def _rhs(self, theta, y, stage, need_jac: bool):
        """``dy (B,N,D)`` and, with ``need_jac``, for each layout entry its tangent recipe:
        ``("copy", j)`` (its derivative is entry j) or ``("top", {d: coef}, Tt)`` with
        ``d(dy_i) = sum_d coef_d T_d + Tt`` (``Tt``: ``(B,N,P_shared)`` or None)."""
        fm = self.forward
        curves, eqs, simple, _ = self._plan()
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
            rt: Any = None  # (B, N, P_shared) when need_jac
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
        A = self.A_inv_list or []
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


def _plus(a, b):
    """``a + b`` with ``a`` None meaning nothing yet."""
    return b if a is None else a + b


def _axpy(e, K, c):
    """``e + c K`` with ``K`` None meaning zero."""
    return e if K is None else e + c * K


def _acc(target: dict, grads: dict, factor) -> None:
    """``target[i] += factor * g_i`` for the non-zero partial derivatives ``grads`` (tensors or floats)."""
    for i, g in grads.items():
        v = factor * g
        target[i] = v if i not in target else target[i] + v
