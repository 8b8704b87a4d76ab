"""Automatic terms that only help (issue 46, item 2): a term a test adds beside a network (powers,
harmonics, a jump) stays only where the fit with it has the lower Akaike criterion than the fit
without it; ``TrainingPreset(auto_terms=False)`` turns the automatic terms off."""

from types import SimpleNamespace

import numpy as np
import pytest

import charcurves as cc
from charcurves.curves import Neural
from charcurves.fitting import PRESETS
from charcurves.fitting._auto_terms import aic, check_layouts, describe
from charcurves.fitting._fit_path import resolve_jumps
from charcurves.templates import get_template

QUICK = PRESETS["default"].replace(n_starts=1, adam_steps=20, lm_max_iter=5, check_auto_terms=True,
                                   auto_terms_rule="aic")
CUBIC = ((), (("f2", (3,)),), ())
NONE = ((), (), ())


def _model(loss, gamma):
    return SimpleNamespace(loss=loss, info={"effective_parameters": gamma})


def test_aic_counts_the_effective_parameters_or_the_added_terms():
    assert aic(_model(0.01, 4.0), 100) == pytest.approx(100 * np.log(0.01) + 8.0)
    assert aic(SimpleNamespace(loss=0.01, info={}), 100, extra=3) == pytest.approx(100 * np.log(0.01) + 6.0)


def test_the_fit_with_the_lower_aic_is_kept_per_record():
    records = [SimpleNamespace(n_samples=1000)] * 3
    masks = [np.ones(1000, bool)] * 3
    with_terms = [_model(0.0043, 12.8), _model(0.00276, 9.0), _model(0.5, 1.0)]
    without = {0: _model(0.00182, 20.5), 1: _model(0.00271, 23.0)}
    asked = []

    def refit(idx):
        asked.append(list(idx))
        return [without[i] for i in idx]

    models, notes = check_layouts(records, with_terms, masks, [CUBIC, CUBIC, NONE], [NONE, NONE, NONE], refit)
    assert asked == [[0, 1]]  # the record whose tests added nothing is not refitted
    # record 0: 1000 ln(0.0043) + 25.6 = -5413.6 against 1000 ln(0.00182) + 41 = -6267.0: without
    # record 1: -5874.5 (with) against -5865.6 (without): the terms stay, though the loss is higher
    assert models[0] is without[0] and models[1] is with_terms[1] and models[2] is with_terms[2]
    assert [n["kept"] for n in notes[:2]] == [False, True] and notes[2] is None
    assert notes[0]["aic_with"] == pytest.approx(1000 * np.log(0.0043) + 25.6)
    assert notes[0]["tested"] == {"jumps": [], "powers": {"f2": [3]}, "harmonics": {}}


def test_resolve_jumps_without_automatic_terms_keeps_the_named_ones(duffing_20db):
    tmpl = get_template("separable")
    reps = {"f1": Neural(symmetry="odd", jump="auto"), "f2": Neural(symmetry="odd")}
    [tested] = resolve_jumps(reps, [duffing_20db], tmpl, [False], PRESETS["default"])
    assert tested == ((), (("f2", (3,)),), ())  # Duffing's spring gets the cubic, no jump
    for kwargs in ({"automatic": False}, {}):
        preset = PRESETS["default"] if kwargs else PRESETS["default"].replace(auto_terms=False)
        assert resolve_jumps(reps, [duffing_20db], tmpl, [False], preset, **kwargs) == [NONE]
    named = {"f1": Neural(symmetry="odd", jump=True), "f2": Neural(symmetry="odd", powers=(3, 5))}
    assert resolve_jumps(named, [duffing_20db], tmpl, [False], PRESETS["default"], automatic=False) == \
        [(("f1",), (("f2", (3, 5)),), ())]


def test_a_fit_records_the_check_and_its_settings_follow_the_choice(duffing_20db):
    """Five LM iterations: the network alone does not reach Duffing's cubic (loss 0.196 measured,
    against 0.0012 with the cubic), so the cubic stays and the fit is the unchecked one."""
    model = cc.fit(duffing_20db, method="nn-cc+sym", preset=QUICK, threads=1, random_state=0)
    note = model.info["automatic_terms"]
    assert note["tested"] == describe(CUBIC) and note["kept"]
    assert note["aic_with"] < note["aic_without"] - 1000 and note["loss_without"] > 100 * note["loss_with"]
    assert model.info["settings"]["polynomial_terms"] == {"f2": [3]} and model.loss == note["loss_with"]
    unchecked = cc.fit(duffing_20db, method="nn-cc+sym", preset=QUICK.replace(check_auto_terms=False), threads=1,
                       random_state=0)
    assert "automatic_terms" not in unchecked.info and unchecked.loss == model.loss
    off = cc.fit(duffing_20db, method="nn-cc+sym", preset=QUICK.replace(auto_terms=False), threads=1, random_state=0)
    assert "automatic_terms" not in off.info and off.info["settings"]["polynomial_terms"] == {}
    assert off.loss == note["loss_without"]  # the fit the check compared is the fit without the terms


def test_the_zoo_runs_a_method_without_its_automatic_terms_under_its_own_label():
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import bench_zoo
    import zoo

    jobs = bench_zoo.jobs_for("seed0", methods=["nn-cc+sym/no-auto", "limit"])
    odd = [n for n, s in zoo.SYSTEMS.items() if s.all_odd()]
    assert len(jobs) == 2 * (len(odd) + len(zoo.SYSTEMS)) and {j[2] for j in jobs} == {"F25", "x30"}
    assert {j[0] for j in jobs if j[1] == "nn-cc+sym/no-auto"} == set(odd)
    assert bench_zoo.VARIANTS == {"no-auto": {"auto_terms": False}, "unchecked": {"check_auto_terms": False},
                                  "checked": {"check_auto_terms": True, "auto_terms_rule": "aic"},
                                  "heldout": {"check_auto_terms": True, "auto_terms_rule": "held-out"}}
    assert bench_zoo.LABELS.index("nn-cc/no-auto") == bench_zoo.LABELS.index("nn-cc") + 1
