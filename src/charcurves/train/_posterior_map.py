"""The map from a gradient-trained equation-error fit's weights to what its model reports (the
curves after the gauge, the gain, free constants and scalars), with its exact Jacobian: what
:class:`._posterior_network.NetworkPosterior` propagates its covariance through."""

from __future__ import annotations

import numpy as np
import torch

__all__ = ["EquationErrorMap"]


class EquationErrorMap:
    """The map from one gradient-trained equation-error fit's weights (the rows of its batched
    problem) to what its model reports: each curve (``factor * f((z - c) / h)``, the factor the
    output scale times the gain on the force side), its gauge shift, the gain, free constants and
    scalars (as :func:`._gradient_fit.fit_gradient` builds the model)."""

    def __init__(self, ctx: dict):
        self.ctx = ctx
        self.template = ctx["template"]

    def report(self, Th: torch.Tensor, grids: dict) -> torch.Tensor:
        """The reported values of the model whose members are the rows of ``Th`` ``(M, P)``: each
        curve on its grid (after the gauge), then the scalars (:meth:`scalar_names`), one vector."""
        c = self.ctx
        names = c["names"]
        gain_col = Th[:, c["gain_index"]] if c["gain_index"] is not None else None
        if c["force_side"] and gain_col is not None:
            g = c["g_est"] / gain_col.mean()
        elif gain_col is not None:
            g = gain_col.mean()
        else:
            g = Th.new_tensor(float(c["gain"]))
        factor = c["s_out"] * g if c["force_side"] else Th.new_tensor(c["s_out"])
        scal = {}
        for j, cname in enumerate(c["const_names"]):
            o = c["offsets"][len(names) + j]
            scal[cname] = Th[:, o].mean() * factor / c["sig_scale"][cname]
        own = {n: scal.pop(f"const:{n}") for n in c["own"]}

        def raw(i, z):
            nm = names[i]
            center, half = c["scales"][nm]
            o = c["offsets"][i]
            p = c["params"][nm]
            u = (torch.as_tensor(np.asarray(z, dtype=float), dtype=Th.dtype) - center) / half
            f = p.evaluate(Th[:, o:o + p.n_params], u.reshape(1, -1).expand(Th.shape[0], -1)).mean(dim=0) * factor
            if nm in own and not c["neural"][nm]:
                f = f + own[nm]
            return f

        offs = {e: scal.pop(f"b{e + 1}") for e in c["offset_keys"] if c["E"] > 1}
        if c["bias_index"] is not None:
            offs[0] = Th[:, c["bias_index"]].mean() * factor
        names_g, off_keys, new_keys, S, O = c["gauge"]
        inputs = torch.stack([raw(i, np.array([0.0]))[0] for i in range(len(names))]
                             + [offs.get(e, Th.new_zeros(())) for e in off_keys]) if (len(names) + len(off_keys)) else Th.new_zeros(0)
        shifts = torch.as_tensor(S, dtype=Th.dtype) @ inputs
        new_off = torch.as_tensor(O, dtype=Th.dtype) @ inputs
        out = [raw(names.index(nm), z) + shifts[names.index(nm)] for nm, z in grids.items()]
        vals = {"gain": g, "offset": Th.new_zeros(())}
        for r, e in enumerate(new_keys):
            vals["offset" if e == 0 else f"b{e + 1}"] = new_off[r]
        vals.update(scal)
        out += [vals[k].reshape(1) for k in self.scalar_names()]
        return torch.cat(out) if out else Th.new_zeros(0)

    def scalar_names(self) -> list[str]:
        c = self.ctx
        names = []
        if self.template.free_gain:
            names.append("gain")
        names_g, off_keys, new_keys, S, O = c["gauge"]
        if 0 in new_keys and np.any(O[new_keys.index(0)] != 0):
            names.append("offset")
        names += [f"b{e + 1}" for e in new_keys if e > 0]
        names += list(self.template.scalar_names)
        return list(dict.fromkeys(names))

    def report_jacobian(self, th: torch.Tensor, grids: dict) -> tuple[np.ndarray, np.ndarray]:
        """The values of :meth:`report` for the single member ``th`` ``(P,)`` and their exact
        Jacobian ``(out, P)``: the curves' own Jacobians (``evaluate_jacobian``), the gain's
        division of every curve and constant (force side) and the gauge's linear shifts."""
        c = self.ctx
        names = c["names"]
        t = th.detach().double().numpy()
        P = t.size
        gi = c["gain_index"]
        dfac = np.zeros(P)
        dg = np.zeros(P)
        if c["force_side"]:
            g = c["g_est"] / t[gi]
            factor = c["s_out"] * g
            dfac[gi] = -factor / t[gi]
            dg[gi] = -g / t[gi]
        else:
            g = t[gi] if gi is not None else float(c["gain"])
            if gi is not None:
                dg[gi] = 1.0
            factor = c["s_out"]

        def lin(o, sig):  # a one-parameter constant times the factor: value and gradient
            d = dfac * t[o] / sig
            d[o] += factor / sig
            return t[o] * factor / sig, d

        scal = {cname: lin(c["offsets"][len(names) + j], c["sig_scale"][cname])
                for j, cname in enumerate(c["const_names"])}
        own = {n: scal.pop(f"const:{n}") for n in c["own"]}

        def raw(i, z):
            nm = names[i]
            center, half = c["scales"][nm]
            o, p = c["offsets"][i], c["params"][nm]
            z = np.asarray(z, dtype=float).reshape(-1)
            u = torch.as_tensor((z - center) / half, dtype=th.dtype).reshape(1, -1)
            with torch.no_grad():
                f, Jf = p.evaluate_jacobian(th[o:o + p.n_params].reshape(1, -1), u)
            f, Jf = f[0].double().numpy(), Jf[0].double().numpy()
            J = np.outer(f, dfac)
            J[:, o:o + p.n_params] += factor * Jf
            v = factor * f
            if nm in own and not c["neural"][nm]:
                v, J = v + own[nm][0], J + own[nm][1][None, :]
            return v, J

        offs = {e: scal.pop(f"b{e + 1}") for e in c["offset_keys"] if c["E"] > 1}
        if c["bias_index"] is not None:
            offs[0] = lin(c["bias_index"], 1.0)
        _, off_keys, new_keys, S, O = c["gauge"]
        zero = (0.0, np.zeros(P))
        at0 = [raw(i, [0.0]) for i in range(len(names))]
        ins = np.array([v[0] for v, _ in at0] + [offs.get(e, zero)[0] for e in off_keys])
        dins = np.array([J[0] for _, J in at0] + [offs.get(e, zero)[1] for e in off_keys]).reshape(-1, P)
        vals, jacs = [], []
        for nm, z in grids.items():
            i = names.index(nm)
            v, J = raw(i, z)
            vals.append(v + S[i] @ ins)
            jacs.append(J + (S[i] @ dins)[None, :])
        sv = {"gain": (g, dg), "offset": zero}
        for r, e in enumerate(new_keys):
            sv["offset" if e == 0 else f"b{e + 1}"] = (float(O[r] @ ins), O[r] @ dins)
        sv.update(scal)
        for k in self.scalar_names():
            vals.append(np.array([sv[k][0]]))
            jacs.append(np.asarray(sv[k][1]).reshape(1, P))
        if not vals:
            return np.zeros(0), np.zeros((0, P))
        return np.concatenate(vals), np.concatenate(jacs)
