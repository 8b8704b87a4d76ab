"""The Laplace posterior of an output-error fit (:func:`._output_error.output_error_fit`).

The multiple-shooting problem's parameters are the curves' weights or coefficients, the scalars,
offsets and gain (shared) and every segment's initial state. At the optimum the Gauss-Newton
matrix of its residuals (the simulated positions against the measured ones, the continuity rows)
plus the evidence's decays is the posterior precision of all of them. The segments' initial
states are nuisance parameters: they are marginalised, which for a Gaussian is the shared block
of the inverse precision (the inverse of the Schur complement ``H_ss - H_si H_ii^-1 H_is``); the
reported values depend on the shared parameters only, so their Jacobian is zero on the initial
states and the band is ``J_s (H^-1)_ss J_s^T``. The covariances (``"hac"`` by default, ``"gauss"``),
the members' mixture and the warnings are those of :mod:`charcurves.train`'s ``laplace_posterior``.
"""

from __future__ import annotations

import time

import numpy as np
import torch

from ..train import attach_posterior, gauge_map, laplace_posterior

__all__ = ["OutputErrorMap", "output_error_posterior"]


class OutputErrorMap:
    """The map from the shooting problem's parameters (one member's row) to what the refitted model
    reports: each curve ``out * f((z - c) / h) + c0`` (``c0`` the part of the curve no parameter
    moves) after the template's gauge, the gain, the free constants and the scalars."""

    def __init__(self, template, problem, curves: dict, thetas: torch.Tensor, gauge):
        self.template, self.gauge = template, gauge
        self.names = list(template.curve_names)
        self.problem = problem
        b = problem.blocks
        self.specs = [(blk.param, problem.block_offsets[i], float(blk.center[0, 0]), float(blk.half[0, 0]),
                       float(blk.out[0, 0])) for i, blk in enumerate(b)]
        self.c0 = []
        for i, nm in enumerate(self.names):  # the constant part: the curve at 0 beyond its parameters' share
            with torch.no_grad():
                f = self._raw(i, thetas, np.array([0.0])).mean(dim=0)
            c0 = float(np.asarray(curves[nm].raw(np.array([0.0])))[0]) - float(f[0])
            trained = float(b[i].shift[0, 0])  # the shift the curve was trained with (finish_model keeps it)
            self.c0.append(c0 + trained if trained else c0)

    def _raw(self, i, Th, z):
        param, o, center, half, out = self.specs[i]
        u = torch.as_tensor((np.asarray(z, dtype=float).reshape(-1) - center) / half, dtype=Th.dtype)
        return out * param.evaluate(Th[:, o:o + param.n_params], u.reshape(1, -1).expand(Th.shape[0], -1))

    def scalar_names(self) -> list[str]:
        names = ["gain"] if self.template.free_gain else []
        _, _, keys, _, O = self.gauge
        if 0 in keys and np.any(O[keys.index(0)] != 0):
            names.append("offset")
        names += [f"b{e + 1}" for e in keys if e > 0]
        return list(dict.fromkeys(names + list(self.template.scalar_names)))

    def _inputs(self, Th, at0):
        p = self.problem
        _, off_keys, _, _, _ = self.gauge
        return [*at0, *[Th[:, p.offset_index[e]].mean() if e in p.offset_index else Th.new_zeros(())
                        for e in off_keys]]

    def report(self, Th: torch.Tensor, grids: dict) -> torch.Tensor:
        """The reported values of the model whose members are the rows of ``Th``."""
        p = self.problem
        _, off_keys, keys, S, O = self.gauge
        at0 = [self._raw(i, Th, [0.0]).mean(dim=0)[0] + self.c0[i] for i in range(len(self.names))]
        ins = torch.stack(self._inputs(Th, at0)) if (at0 or off_keys) else Th.new_zeros(0)
        shifts = torch.as_tensor(S, dtype=Th.dtype) @ ins
        new_off = torch.as_tensor(O, dtype=Th.dtype) @ ins
        out = []
        for nm, z in grids.items():
            i = self.names.index(nm)
            out.append(self._raw(i, Th, z).mean(dim=0) + self.c0[i] + shifts[i])
        vals = {"gain": Th[:, p.gain_index].mean() if p.gain_index is not None else Th.new_tensor(p.gain)}
        for r, e in enumerate(keys):
            vals["offset" if e == 0 else f"b{e + 1}"] = new_off[r]
        vals.update({s: Th[:, p.scalar_index[s]].mean() for s in p.scalars})
        out += [vals[k].reshape(1) for k in self.scalar_names()]
        return torch.cat(out) if out else Th.new_zeros(0)

    def report_jacobian(self, th: torch.Tensor, grids: dict) -> tuple[np.ndarray, np.ndarray]:
        """Values for the single member ``th`` and their exact Jacobian (zero on the initial states)."""
        p = self.problem
        P = th.numel()
        _, off_keys, keys, S, O = self.gauge

        def raw(i, z):
            param, o, center, half, out = self.specs[i]
            u = torch.as_tensor((np.asarray(z, dtype=float).reshape(-1) - center) / half, dtype=th.dtype)
            with torch.no_grad():
                f, Jf = param.evaluate_jacobian(th[o:o + param.n_params].reshape(1, -1), u.reshape(1, -1))
            J = np.zeros((u.numel(), P))
            J[:, o:o + param.n_params] = out * Jf[0].double().numpy()
            return out * f[0].double().numpy() + self.c0[i], J

        def unit(j):
            e = np.zeros(P)
            e[j] = 1.0
            return e

        t = th.detach().double().numpy()
        at0 = [raw(i, [0.0]) for i in range(len(self.names))]
        offs = [(t[p.offset_index[e]], unit(p.offset_index[e])) if e in p.offset_index else (0.0, np.zeros(P))
                for e in off_keys]
        ins = np.array([v[0] for v, _ in at0] + [v for v, _ in offs])
        dins = np.array([J[0] for _, J in at0] + [d for _, d in offs]).reshape(-1, P)
        vals, jacs = [], []
        for nm, z in grids.items():
            i = self.names.index(nm)
            v, J = raw(i, z)
            vals.append(v + S[i] @ ins)
            jacs.append(J + (S[i] @ dins)[None, :])
        sv = {"gain": (t[p.gain_index], unit(p.gain_index)) if p.gain_index is not None else (p.gain, np.zeros(P))}
        for r, e in enumerate(keys):
            sv["offset" if e == 0 else f"b{e + 1}"] = (float(O[r] @ ins), O[r] @ dins)
        sv.update({s: (t[p.scalar_index[s]], unit(p.scalar_index[s])) for s in p.scalars})
        for k in self.scalar_names():
            vals.append(np.array([sv[k][0]]))
            jacs.append(np.asarray(sv[k][1]).reshape(1, P))
        if not vals:
            return np.zeros(0), np.zeros((0, P))
        return np.concatenate(vals), np.concatenate(jacs)


def _owners(problem, names: list) -> list[str]:
    out = ["a segment's initial state"] * problem.n_params
    for i, o in enumerate(problem.block_offsets):
        out[o:o + problem.blocks[i].n_params] = [names[i]] * problem.blocks[i].n_params
    for s, j in problem.scalar_index.items():
        out[j] = s
    for e, j in problem.offset_index.items():
        out[j] = "the free constant" if e == 0 else f"b{e + 1}"
    if problem.gain_index is not None:
        out[problem.gain_index] = "the gain"
    return out


def output_error_posterior(model, problem, theta: torch.Tensor, members: np.ndarray, restore: dict | None = None) -> None:
    """Attach the Laplace posterior of the output-error fit to ``model`` (the refitted model; its
    members are the rows ``members`` of ``theta``, the trained rows of the shooting ``problem``).
    ``restore``: ``{column: value per row}`` of frozen columns the model holds at another value (a
    jump's width, trained smooth and sharpened afterwards): the bands are those of the sharpened
    curves, the precision that of the problem that ran."""
    t0 = time.perf_counter()
    template = model.template
    idx = torch.as_tensor(np.asarray(members, dtype=np.int64))
    every = idx.numel() == problem.K and bool((idx == torch.arange(problem.K)).all())
    sub = problem if every else problem.subset(idx)  # all rows: the free run at theta is remembered
    th = theta if every else theta[idx]
    pinned = {nm: bool(c.pinned_at_zero) for nm, c in model.curves.items()}
    gauge = gauge_map(template, list(template.curve_names), sorted(problem.offset_index), pinned)
    shown = th.clone()
    for col, values in (restore or {}).items():
        shown[:, col] = torch.as_tensor(np.asarray(values, dtype=float)[np.asarray(members)], dtype=shown.dtype)
    mapping = OutputErrorMap(template, sub, model.curves, shown, gauge)
    O = problem.O
    scale = float(problem.scales[problem.out_index[0]])
    post = laplace_posterior(sub, th, mapping, _owners(problem, list(template.curve_names)),
                             instants=lambda a: a.reshape(-1, O, a.shape[-1]).sum(axis=1),  # outputs of one instant
                             noise_scale=scale**2 * problem.n_data,
                             label="laplace (gauss-newton of output error, initial states marginalised)",
                             report_theta=shown if restore else None)
    attach_posterior(model, post, t0)
