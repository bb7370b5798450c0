"""The thresholds of phase 1 sit in one module, each with its rule and reason, as the ledger
(docs/rules.md) names them."""

import ast
import importlib
import re
from pathlib import Path

import numpy as np
import pytest

from zeroset import thresholds

ROOT = Path(__file__).resolve().parents[1]
LEDGER = (ROOT / "docs" / "rules.md").read_text(encoding="utf-8")
SOURCE = Path(thresholds.__file__).read_text(encoding="utf-8")
#: Rules with an entry in the ledger ("### R8. Per-point radius").
RULES = set(re.findall(r"^### (R\d+)\.", LEDGER, re.MULTILINE))


def _documented_names() -> dict[str, str]:
    """Each name assigned in thresholds.py -> the ``#:`` comment block above its line."""
    lines = SOURCE.splitlines()
    found = {}
    for node in ast.parse(SOURCE).body:
        if not isinstance(node, ast.Assign):
            continue
        targets = node.targets[0]
        names = [t.id for t in getattr(targets, "elts", [targets])]
        row = node.lineno - 2
        while row >= 0 and not lines[row].startswith("#:"):
            row -= 1  # a second assignment under the same comment
            if row < 0 or not re.match(r"^[A-Z_]+( |,)", lines[row + 1]):
                break
        block = []
        while row >= 0 and lines[row].startswith("#:"):
            block.insert(0, lines[row][2:])
            row -= 1
        for name in names:
            found[name] = " ".join(block)
    return found


DOCUMENTED = _documented_names()


def test_every_threshold_names_its_rule_and_reason():
    assert len(DOCUMENTED) >= 50  # the module holds the thresholds, not a stub
    for name, comment in DOCUMENTED.items():
        rules = set(re.findall(r"R\d+", comment))
        assert rules, f"{name} names no rule"
        assert rules <= RULES, f"{name} names rules the ledger lacks: {rules - RULES}"
        assert "**Derived**" in comment or "**Chosen**" in comment, f"{name} gives no reason"


def test_the_modules_apply_the_thresholds_not_copies_of_them():
    # A phase-1 module that uses a threshold imports it; none defines its own value of the
    # name (the inspection, phase 2 and the synthetic clouds have their own).
    package = Path(thresholds.__file__).parent
    for path in [*package.glob("*.py"), *package.glob("_kernels/*.py")]:
        if path.name == "thresholds.py":
            continue
        for node in ast.parse(path.read_text(encoding="utf-8")).body:
            if isinstance(node, ast.Assign):
                for target in node.targets:
                    for leaf in getattr(target, "elts", [target]):
                        assert getattr(leaf, "id", None) not in DOCUMENTED, (
                            f"{path.name} redefines {leaf.id}"
                        )


def _ledger_constants() -> list[tuple[str, str, str | None]]:
    """(name, value as written, module named in brackets or None) in the entries' fields."""
    found = []
    for field in re.findall(r"^- \*\*Constants\*\*: (.*)$", LEDGER, re.MULTILINE):
        for segment in field.rstrip(".").split(";"):
            module = re.search(r"\(`?([\w/.]+?)(?:\.py)?`?[:,)]", segment)
            for name, value in re.findall(r"`([A-Z_][A-Z0-9_]*) = ([^`]+)`", segment):
                found.append((name, value, module.group(1) if module else None))
    return found


@pytest.mark.parametrize("name, value, module", _ledger_constants())
def test_the_ledger_gives_each_constant_its_value(name, value, module):
    if name in DOCUMENTED:
        holder = thresholds
    else:
        assert module is not None, f"{name} is no threshold, and the ledger names no module"
        if module == "registration":
            pytest.importorskip("small_gicp")
        holder = importlib.import_module("zeroset." + module.replace("/", "."))
    actual = getattr(holder, name)
    namespace = {"np": np, **{k: getattr(holder, k) for k in dir(holder) if k.isupper()}}
    assert np.all(np.asarray(eval(value, namespace)) == np.asarray(actual)), name


def test_every_threshold_is_in_the_ledger():
    named = {name for name, _, _ in _ledger_constants()}
    assert set(DOCUMENTED) - named == set()
