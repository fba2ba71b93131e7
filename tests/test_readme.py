"""The README's examples are real: its XML validates and its node runs."""

from __future__ import annotations

import re

import numpy as np
import shapely
from conftest import ROOT

import sengine
from sengine import Layer
from sengine.registry import get, load_plugin, names
from sengine.xmlconfig import parse

README = (ROOT / "README.md").read_text()


def blocks_in(text: str, lang: str) -> list[str]:
    return re.findall(rf"```{lang}\n(.*?)```", text, flags=re.S)


def blocks(lang: str) -> list[str]:
    return blocks_in(README, lang)


def test_quick_start_has_exactly_two_commands():
    section = README.split("## Quick start", 1)[1].split("\n## ", 1)[0]
    commands = blocks_in(section, "sh")
    assert len(commands) == 2
    assert "sengine run configs/manhattan.xml" in commands[0]
    assert commands[1].strip().endswith("pytest")
    # .ci/run installs the same way, lints, and runs every test, the slow ones too
    ci = (ROOT / ".ci" / "run").read_text()
    install = commands[1].strip().rpartition(" && ")[0]
    assert install in ci and ".venv/bin/ruff check ." in ci and ".venv/bin/ruff format --check ." in ci
    assert ci.rstrip().endswith('.venv/bin/pytest -m "slow or not slow"')


def test_readme_config_is_valid(tmp_path):
    (xml,) = blocks("xml")
    path = tmp_path / "readme.xml"
    path.write_text(xml)
    root = parse(path, "readme.xml")
    assert root.find("city").get("size") == "6000 4000"
    # without its example plugin the network is complete: types, ports and parameters check out
    path.write_text(re.sub(r"\s*<plugin [^>]*/>", "", xml))
    bound = sengine.load(path).validate()
    assert bound.nodes["lots"].name == "lots.paris" and bound.nodes["lots"].p.depth == 18.0
    assert ("lots", "lots", "bigLots", "input") in bound.edges


def test_readme_lists_every_builtin_node():
    for name in names():
        if not get(name).__module__.startswith("sengine.nodes."):
            continue  # a plugin another test registered
        assert f"`{name}`" in README, f"node {name} is missing from the README's node reference"


def test_readme_node_registers_and_runs(tmp_path):
    code = next(b for b in blocks("python") if "@register" in b)
    (tmp_path / "readme_courtyards.py").write_text(code)
    load_plugin(str(tmp_path / "readme_courtyards.py"))
    cls = get("mycity.courtyards")
    lots = Layer.from_geoms(shapely.box(np.arange(3) * 50.0, 0, np.arange(3) * 50.0 + 40, 40))
    out = cls("c", {"depth": "10"}).run(lots=lots)["lots"]
    assert np.allclose(shapely.area(out.geometry), 40 * 40 - 20 * 20)


def test_readme_python_example_runs(tmp_path, monkeypatch, capsys):
    code = next(b for b in blocks("python") if "sengine.load" in b)
    monkeypatch.chdir(ROOT)
    exec(compile(code.replace('"out/manhattan"', repr(str(tmp_path / "m"))), "README.md", "exec"), {})
    printed = capsys.readouterr().out
    lots = int(re.search(r"'lots': (\d+)", printed).group(1))
    assert 6500 <= lots <= 8000 and (tmp_path / "m" / "stats.json").exists()  # the paper's ~7,000 (7,471)
