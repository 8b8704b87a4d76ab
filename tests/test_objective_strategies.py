"""Objectives are strategies: a new objective is one subclass of ``Objective``, defined here in the
test, that the estimator runs with no edit to the library; the library's own objectives answer the
same two questions (does a record go on from its equation-error start, and how)."""

from __future__ import annotations

import numpy as np
import pytest

import charcurves as cc
from charcurves.fitting import CharacteristicCurves, get_preset
from charcurves.objectives import OBJECTIVES, Auto, EquationError, Objective, OutputError, resolve_objective
from charcurves.systems import get_system

Z = np.linspace(-1.5, 1.5, 121)
TEMPLATE = dict(f1=cc.Polynomial(degree=1, symmetry="odd"), f2=cc.Polynomial(degree=3, symmetry="odd"))
SHORT_OE = dict(segment_length=16, substeps=1, max_iter=2)  # a short output-error run


@pytest.fixture(scope="module")
def records():
    clean = get_system("duffing").simulate(t_end=20.0, n_points=500)
    measured = cc.corrupt(clean, 30, on="state", seed=0)  # x only: derivatives estimated
    given = cc.corrupt(clean, 30, on="force", seed=0)  # derivatives given as columns
    return measured, given


def _estimator(objective):
    return CharacteristicCurves(template=cc.Separable(**TEMPLATE), objective=objective)


def _curves(model) -> dict:
    return {name: np.asarray(c(Z), dtype=float) for name, c in model.curves.items()}


class Recorded(Objective):
    """Refines every record by keeping its start, and writes down what it was called with."""

    name = "recorded"

    def __init__(self, note: str = "ran"):
        self.note = note
        self.calls: list = []

    def refines(self, estimated, preset):
        return True

    def refine(self, start, prepared, measured, *, preset, progress=None):
        self.calls.append((prepared.has_derivatives, measured, preset.name))
        start.info["recorded"] = self.note
        return start


class ShortShooting(Objective):
    """Output error on every record, composed from the library's OutputError (not a subclass of it)."""

    name = "short-shooting"

    def refines(self, estimated, preset):
        return True

    def refine(self, start, prepared, measured, *, preset, progress=None):
        return OutputError(**SHORT_OE).refine(start, prepared, measured, preset=preset, progress=progress)


class Interrupting(Recorded):
    name = "interrupting"

    def refine(self, start, prepared, measured, *, preset, progress=None):
        raise KeyboardInterrupt


def test_a_custom_objective_runs_on_every_record_it_refines(records):
    measured, given = records
    objective = Recorded(note="seen")
    models = _estimator(objective).fit_many([measured, given])
    # called once per record, with the prepared record (derivatives estimated or given) and the measured one
    assert [(has_d, rec is raw, name) for (has_d, rec, name), raw in zip(objective.calls, (measured, given))] == \
        [(True, True, "default"), (True, True, "default")]
    assert [m.info["recorded"] for m in models] == ["seen", "seen"]
    assert [(m.info["settings"]["objective"], m.info["settings"]["objective_requested"]) for m in models] == \
        [("recorded", "recorded"), ("recorded", "recorded")]


def test_a_custom_objective_that_keeps_its_start_gives_the_equation_error_fit(records):
    measured, _ = records
    mine = _estimator(Recorded()).fit(measured).model_
    ee = _estimator(EquationError()).fit(measured).model_
    for name, values in _curves(ee).items():
        assert np.array_equal(_curves(mine)[name], values), name
    assert ee.info["settings"]["objective"] == "equation-error" and "output_error" not in mine.info


def test_a_custom_objective_composed_of_output_error_gives_the_output_error_fit(records):
    measured, _ = records
    mine = _estimator(ShortShooting()).fit(measured).model_
    oe = _estimator(OutputError(**SHORT_OE)).fit(measured).model_
    assert mine.info["output_error"]["status"] == "ok"
    for name, values in _curves(oe).items():  # linear curves: the start's ensemble rule does not enter
        assert np.array_equal(_curves(mine)[name], values), name
    assert mine.info["settings"]["objective"] == "short-shooting"
    assert oe.info["settings"]["objective"] == "output-error"


def test_ctrl_c_in_an_objective_keeps_the_starts_and_says_so(records):
    measured, given = records
    models = _estimator(Interrupting()).fit_many([measured, given])
    assert [m.info.get("refine") for m in models] == ["skipped: interrupted"] * 2
    assert all(m.info["interrupted"] is True for m in models)


def test_auto_chooses_per_record(records):
    measured, given = records
    models = _estimator(Auto(output_error=OutputError(**SHORT_OE))).fit_many([measured, given])
    assert [(m.info["settings"]["objective"], m.info["settings"]["objective_requested"]) for m in models] == \
        [("output-error", "auto"), ("equation-error", "auto")]
    assert models[0].info["output_error"]["status"] == "ok" and "output_error" not in models[1].info


def test_the_library_objectives_answer_the_two_questions():
    default, paper = get_preset("default"), get_preset("paper")
    table = {type(o).__name__: [(o.refines(e, p), o.applied(e, p)) for e in (False, True) for p in (default, paper)]
             for o in (EquationError(), OutputError(), Auto())}
    ee, oe = ("equation-error", "output-error")
    assert table == {
        "EquationError": [(False, ee)] * 4,
        "OutputError": [(True, oe)] * 4,
        "Auto": [(False, ee), (False, ee), (True, oe), (False, ee)],  # estimated, not the paper's preset
    }
    mean = default.replace(combine="mean", combine_tol=0.1)
    assert OutputError().start_preset(mean, [True]).combine_tol == float("inf")
    assert Auto().start_preset(mean, [True, False]) is mean  # a record stays at equation error: its start combines
    assert EquationError().start_preset(mean, [True]) is mean


def test_resolve_objective_turns_every_spelling_into_an_object():
    assert [resolve_objective(name) for name in OBJECTIVES] == [Auto(), EquationError(), OutputError()]
    assert resolve_objective(None) == Auto()
    assert resolve_objective(None, refine="none") == EquationError()
    assert resolve_objective("output-error", refine_options={"hold": "zoh", "max_nfev": 7}) == \
        OutputError(hold="zoh", max_iter=7)
    assert resolve_objective(Auto(), refine_options={"substeps": 2}) == Auto(output_error=OutputError(substeps=2))
    given = Auto(output_error=OutputError(hold="zoh"))
    assert resolve_objective(given, refine_options={"substeps": 2}) is given  # the object keeps its own settings
    mine = Recorded()
    assert resolve_objective(mine, refine="none") is mine


def test_bad_objectives_are_refused_with_the_fix():
    class Nameless(Recorded):
        name = ""

    with pytest.raises(cc.ConfigError, match="objective Nameless has no name; set the class attribute name"):
        resolve_objective(Nameless())
    with pytest.raises(cc.ConfigError, match=r"unknown objective 'weak-form'; choose one of auto, equation-error, "
                                             r"output-error, .*a subclass of Objective"):
        resolve_objective("weak-form")
    with pytest.raises(cc.ConfigError, match=r"Auto\(output_error=...\) takes an OutputError"):
        resolve_objective(Auto(output_error=EquationError()))
    with pytest.raises(TypeError, match="abstract"):
        Objective()  # type: ignore[abstract]


def test_a_custom_objective_has_the_parameter_contract():
    objective = Recorded(note="a")
    assert objective.get_params() == {"note": "a"}
    assert objective.set_params(note="b").note == "b"
    assert repr(objective) == "Recorded(note='b')" and objective == Recorded(note="b") and objective != Recorded()
    est = _estimator(objective).set_params(objective__note="c")
    assert est.objective.note == "c"


def test_the_command_line_offers_the_registered_objectives():
    from charcurves.cli._parser import build_parser

    fit = next(a for a in build_parser("0")._actions if a.dest == "command").choices["fit"]
    choices = next(a.choices for a in fit._actions if a.dest == "objective")
    assert tuple(choices) == OBJECTIVES == ("auto", "equation-error", "output-error")


def test_the_example_of_the_objectives_page_runs(records):
    """The code block of docs/api/objectives.md, run as written on a record with derivatives given."""
    import re
    from pathlib import Path

    page = (Path(__file__).resolve().parents[1] / "docs" / "api" / "objectives.md").read_text(encoding="utf-8")
    [code] = re.findall(r"```python\n(.*?)```", page, re.S)
    namespace = {"record": records[1]}
    exec(compile(code, "docs/api/objectives.md", "exec"), namespace)  # the page's own example
    model = namespace["model"]
    assert model.info["settings"]["objective"] == "short-output-error"
    assert model.info["output_error"]["status"] == "ok"  # output error ran on a record whose derivatives were given
    assert namespace["EveryRecordShort"]().get_params() == {"max_iter": 5}
