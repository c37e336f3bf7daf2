"""The undeclared-effect cases of benchmarks/eval_undeclared.py, on hand-made TOMLs and
records (no discovery run)."""

from __future__ import annotations

import json
import tomllib
from types import SimpleNamespace

import numpy as np
import pytest

from schemas.hoist import EXAMPLE_HOIST, load_hoist


@pytest.fixture(scope="module")
def undeclared(benchmark_script):
    with benchmark_script("eval_undeclared") as module:
        yield module


def test_an_effect_taken_out_leaves_the_rest_of_the_description_as_it_was(undeclared, tmp_path):
    text = EXAMPLE_HOIST.read_text()
    declared = tomllib.loads(text)["model"]["effects"]
    assert len(declared) >= 3
    dropped = declared[1]
    rewritten = undeclared.without_effect(text, dropped)
    parsed, original = tomllib.loads(rewritten), tomllib.loads(text)
    assert parsed["model"]["effects"] == [e for e in declared if e != dropped]
    original["model"].pop("effects")
    parsed["model"].pop("effects")
    assert parsed == original
    path = tmp_path / "hoist.toml"
    path.write_text(rewritten)
    assert dropped not in load_hoist(path).model.effects  # a description ropeload reads
    with pytest.raises(KeyError, match="not declared"):
        undeclared.without_effect(rewritten, dropped)


def test_a_record_as_described_and_each_effect_taken_out_are_its_cases(undeclared, tmp_path):
    text = '[hoist]\nname = "h"\n\n[model]\neffects = [\n  "a",\n  "b",\n]\n'
    toml = tmp_path / "h.toml"
    toml.write_text(text)
    record = undeclared.Record("r", tmp_path / "r.csv.gz", toml)
    got = [(hidden, tomllib.loads(t)["model"]["effects"]) for hidden, t in undeclared.cases(record)]
    assert got == [("none", ["a", "b"]), ("a", ["b"]), ("b", ["a"])]


def test_records_that_hide_nothing_are_the_none_trials_and_the_days(undeclared, tmp_path):
    trials, days = tmp_path / "trials", tmp_path / "days"
    for name in ("trial_000", "trial_001"):
        (trials / name).mkdir(parents=True)
    key = {"trials": [{"trial": "trial_000", "hidden_effect": "seal_friction"},
                      {"trial": "trial_001", "hidden_effect": "none"}]}  # fmt: skip
    (trials / "answers.json").write_text(json.dumps(key))
    for name in ("trial_000", "trial_001"):
        (trials / name / f"{name}.csv.gz").write_bytes(b"")
        (trials / name / "hoist.toml").write_text("")
    days.mkdir()
    for name in ("mine_day7", "mine_day8"):
        (days / f"{name}.csv.gz").write_bytes(b"")
    (days / "mine_day7.hoist.toml").write_text("")  # day 8 has no description: left out
    names = [r.name for r in undeclared.full_records(trials, days)]
    assert names == ["trial_001", "mine_day7"]


def test_the_excess_is_what_the_effect_adds_to_the_records_own_gap(undeclared):
    def outcome(gap):
        return SimpleNamespace(report={"gap_before_pa": gap, "noise_pa": 5e3})

    # 13 kPa as described, 18.5 kPa with the effect out: sqrt(18.5^2 - 13^2) = 13.16 kPa
    assert undeclared.excess_over_noise(outcome(18.5e3), outcome(13e3)) == pytest.approx(
        13.162e3 / 5e3, rel=1e-4
    )
    assert undeclared.excess_over_noise(outcome(12e3), outcome(13e3)) == 0.0
    crashed = SimpleNamespace(report={})
    assert np.isnan(undeclared.excess_over_noise(outcome(18.5e3), crashed))
    assert np.isnan(undeclared.excess_over_noise(crashed, outcome(13e3)))


def test_only_the_model_tables_effects_key_is_rewritten(undeclared):
    text = (
        '[other]\neffects = ["kept"]\n\n[model]\n# a comment ]\neffects = ["a", "b"]\n'
        "\n[after]\nx = 1\n"
    )
    rewritten = undeclared.without_effect(text, "a")
    assert tomllib.loads(rewritten) == {
        "other": {"effects": ["kept"]},
        "model": {"effects": ["b"]},
        "after": {"x": 1},
    }
    with pytest.raises(ValueError, match="could not be rewritten"):
        undeclared.without_effect('model = {effects = ["a", "b"]}\n', "a")
