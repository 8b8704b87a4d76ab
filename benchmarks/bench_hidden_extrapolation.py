"""CPU cost and free run of a hidden-state fit with and without linear continuation of its curves.

Two-tank (``TwoTank``, 300 samples over 300 s, seed 0, the upper level hidden), 4 seeded starts,
degree-10 polynomials: ``fit_state_space(..., extrapolation="linear")`` (``ContinuedPolynomial``)
against the default plain polynomials, one torch thread. Prints ``info["cpu_seconds"]``, the
free-run RMSE of the lower level and the Levenberg-Marquardt iterations per stage.

Run: ``python benchmarks/bench_hidden_extrapolation.py``
"""

from __future__ import annotations


def main() -> int:
    import torch

    from charcurves.fitting import fit_state_space
    from charcurves.systems import TwoTank
    from charcurves.templates import StateSpace

    torch.set_num_threads(1)
    record = TwoTank().simulate(n_points=300, t_end=300.0, seed=0)
    template = StateSpace("x1' = g*F - f1(x1); x2' = f1(x1) - f2(x2)", measured={"x2": "x"})
    for extrapolation in ("linear", "polynomial"):
        model = fit_state_space(template, record, seed=0, extrapolation=extrapolation)
        print(extrapolation, "cpu", round(model.info["cpu_seconds"], 1), "free run", model.info["free_run_rmse"],
              "iterations", [s["lm_iterations"] for s in model.info["stages"]], flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
