"""The README's example runs as written (so the front page cannot rot) and the page stays short."""

from __future__ import annotations

import pathlib
import re

ROOT = pathlib.Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")


def _blocks(lang: str) -> list[str]:
    return re.findall(rf"```{lang}\n(.*?)```", README, flags=re.S)


def test_the_python_example_fits_duffing_within_its_noise(tmp_path, monkeypatch):
    [code] = _blocks("python")
    monkeypatch.chdir(tmp_path)
    printed: list = []
    scope = {"print": printed.append}
    exec(compile(code, "README.md", "exec"), scope)  # noqa: S102 - the README's own code
    [errors] = printed
    # 20 dB on F, 1000 samples: the fit is at 1.8e-3 / 4.2e-3 (normalised RMSE); a curve with the wrong
    # shape (a missing cubic, a sign error) is above 0.1
    assert set(errors) == {"f1", "f2"}
    assert errors["f1"] < 5e-3 and errors["f2"] < 1e-2, errors
    assert (tmp_path / "duffing-model" / "model.json").exists()


def test_the_cli_example_names_commands_and_options_that_exist():
    from charcurves.cli._parser import build_parser

    parser = build_parser("0")
    [shell] = [b for b in _blocks("bash") if "charcurves simulate" in b]
    for line in shell.strip().splitlines():
        argv = line.split("#")[0].split()[1:]
        parser.parse_args(argv)  # exits 2 on an unknown command or option


def test_the_readme_is_at_most_900_words():
    prose = re.sub(r"```.*?```", " ", README, flags=re.S)
    assert len(prose.split()) <= 900
