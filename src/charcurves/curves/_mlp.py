"""Batched multilayer perceptrons for univariate curves, with their exact parameter Jacobian.

K independent networks are stored as stacked weight tensors ``W[l]: (K, n_in, n_out)`` so that
ensembles, noise realisations and SNR levels train as one batched computation. The Jacobian of
the outputs with respect to all weights is formed by one forward and one backward sweep of
batched matmuls (per-sample outer products), which for these small networks is far cheaper than
``torch.func.jacfwd``/``jacrev`` and makes Levenberg-Marquardt refinement practical.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import torch

__all__ = ["ACTIVATIONS", "BatchedMLP"]


def _tanh(z):
    h = torch.tanh(z)
    return h, 1.0 - h * h


def _relu(z):
    return torch.relu(z), (z > 0).to(z.dtype)


def _softplus(z):
    return torch.nn.functional.softplus(z), torch.sigmoid(z)


def _gelu(z):
    cdf = 0.5 * (1.0 + torch.erf(z / math.sqrt(2.0)))
    pdf = torch.exp(-0.5 * z * z) / math.sqrt(2.0 * math.pi)
    return z * cdf, cdf + z * pdf


def _silu(z):
    s = torch.sigmoid(z)
    return z * s, s * (1.0 + z * (1.0 - s))


#: name -> function returning (activation, derivative)
ACTIVATIONS = {"tanh": _tanh, "relu": _relu, "softplus": _softplus, "gelu": _gelu, "silu": _silu}

#: name -> the activation alone (the same expressions as the first value of ``ACTIVATIONS``)
_VALUES = {"tanh": torch.tanh, "relu": torch.relu, "softplus": torch.nn.functional.softplus,
           "gelu": lambda z: z * (0.5 * (1.0 + torch.erf(z / math.sqrt(2.0)))),
           "silu": lambda z: z * torch.sigmoid(z)}


class BatchedMLP:
    """K independent 1 -> hidden -> ... -> 1 networks as flat parameter vectors.

    Parameters live outside the object (a ``(K, P)`` tensor) so that optimisers can treat every
    component of a model uniformly; this class only knows the layout.

    Examples
    --------
    >>> import torch
    >>> from charcurves.curves import BatchedMLP
    >>> mlp = BatchedMLP(hidden=(8, 8), activation="tanh")
    >>> mlp.n_params
    97
    >>> theta = mlp.init(3, torch.Generator().manual_seed(0))
    >>> mlp.forward(theta, torch.linspace(-1, 1, 5, dtype=torch.float64)).shape
    torch.Size([3, 5])
    """

    def __init__(self, hidden: Sequence[int], activation: str = "tanh"):
        if activation not in ACTIVATIONS:
            raise ValueError(f"unknown activation {activation!r}; choose one of {sorted(ACTIVATIONS)}")
        self.hidden = tuple(int(h) for h in hidden)
        if not self.hidden or min(self.hidden) < 1:
            raise ValueError(f"hidden layer sizes must be positive integers, got {hidden!r}")
        self.activation = activation
        self._act = ACTIVATIONS[activation]
        sizes = (1, *self.hidden, 1)
        self.layers = list(zip(sizes[:-1], sizes[1:]))
        self.n_params = sum(i * o + o for i, o in self.layers)

    def init(self, K: int, generator: torch.Generator, dtype=torch.float64) -> torch.Tensor:
        """PyTorch's default Linear initialisation (uniform in ±1/sqrt(fan_in)), K models."""
        chunks = []
        for fan_in, fan_out in self.layers:
            bound = 1.0 / math.sqrt(fan_in)
            W = (torch.rand(K, fan_in * fan_out, generator=generator, dtype=dtype) * 2 - 1) * bound
            b = (torch.rand(K, fan_out, generator=generator, dtype=dtype) * 2 - 1) * bound
            chunks += [W, b]
        return torch.cat(chunks, dim=1)

    def _unpack(self, theta: torch.Tensor):
        K = theta.shape[0]
        out, o = [], 0
        for fan_in, fan_out in self.layers:
            W = theta[:, o : o + fan_in * fan_out].reshape(K, fan_in, fan_out)
            o += fan_in * fan_out
            b = theta[:, o : o + fan_out].reshape(K, 1, fan_out)
            o += fan_out
            out.append((W, b))
        return out

    def forward(self, theta: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """Outputs ``(K, N)`` for inputs ``u`` of shape ``(K, N)`` or ``(N,)``."""
        return self.forward_unpacked(self._unpack(theta), u)

    def forward_unpacked(self, layers, u: torch.Tensor) -> torch.Tensor:
        """:meth:`forward` with the weights already unpacked (``_unpack``: callers that evaluate the
        same weights many times unpack them once)."""
        h = u.unsqueeze(-1) if u.dim() == 2 else u.reshape(1, -1, 1).expand(layers[0][0].shape[0], -1, 1)
        last = len(layers) - 1
        act = _VALUES[self.activation]
        for i, (W, b) in enumerate(layers):
            h = torch.baddbmm(b, h, W)
            if i < last:
                h = act(h)
        return h.squeeze(-1)

    def forward_derivative(self, theta: torch.Tensor, u: torch.Tensor):
        """Outputs ``(K, N)`` and their derivative with respect to the input ``u`` (forward mode)."""
        return self.forward_jacobian(theta, u, with_input_derivative=True)[::2]

    def forward_jacobian(self, theta: torch.Tensor, u: torch.Tensor, *, with_input_derivative: bool = False):
        """Outputs ``(K, N)`` and their Jacobian ``(K, N, P)`` with respect to ``theta``; with
        ``with_input_derivative`` also ``d outputs / d u`` ``(K, N)`` (propagated forward alongside)."""
        K = theta.shape[0]
        h = u.unsqueeze(-1) if u.dim() == 2 else u.reshape(1, -1, 1).expand(K, -1, 1)
        layers = self._unpack(theta)
        inputs, derivs = [], []
        dh = torch.ones_like(h) if with_input_derivative else None
        for i, (W, b) in enumerate(layers):
            inputs.append(h)
            z = torch.baddbmm(b, h, W)
            if dh is not None:
                dh = torch.bmm(dh, W)
            if i < len(layers) - 1:
                h, d = self._act(z)
                derivs.append(d)
                if dh is not None:
                    dh = d * dh
            else:
                h = z
        y = h.squeeze(-1)
        # backward sweep: delta_l = d y / d z_l, shape (K, N, n_out_l)
        N = y.shape[1]
        delta = torch.ones(K, N, 1, dtype=theta.dtype, device=theta.device)
        blocks: list[Any] = [None] * len(layers)  # each filled below
        for i in range(len(layers) - 1, -1, -1):
            W, _ = layers[i]
            hin = inputs[i]
            gW = (hin.unsqueeze(-1) * delta.unsqueeze(-2)).reshape(K, N, -1)
            blocks[i] = torch.cat([gW, delta], dim=2)
            if i > 0:
                delta = torch.bmm(delta, W.transpose(1, 2)) * derivs[i - 1]
        if with_input_derivative:
            assert dh is not None
            return y, torch.cat(blocks, dim=2), dh.squeeze(-1)
        return y, torch.cat(blocks, dim=2)
