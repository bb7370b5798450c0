"""A run's stats follow a declared schema: every key is looked up, combined as declared, and
documented."""

import re
from pathlib import Path

import pytest

from zeroset.stats import COMBINES, SCHEMA, add_counts, declared

METHOD = Path(__file__).resolve().parents[1] / "docs" / "method.md"


def test_counts_combine_as_declared():
    total = add_counts({}, {"outliers": 3, "widest_hole_filled": 0.5, "faces": 10})
    add_counts(total, {"outliers": 4, "widest_hole_filled": 0.25})
    assert total == {"outliers": 7, "widest_hole_filled": 0.5, "faces": 10}
    with pytest.raises(ValueError, match="'faces' is set once"):
        add_counts(total, {"faces": 12})


def test_an_undeclared_count_is_refused():
    with pytest.raises(KeyError, match="'outlier' is not declared"):
        add_counts({}, {"outlier": 1})
    with pytest.raises(KeyError, match="'tile' is not declared"):
        declared({"tiles": 2, "tile": 1})


def test_every_count_is_documented():
    assert all(count.meaning and count.combine in COMBINES for count in SCHEMA.values())
    table = re.findall(r"^\| `(\w+)` \| (.+) \| (\w+) \|$", METHOD.read_text(), re.MULTILINE)
    assert [(k, m, c) for k, m, c in table] == [
        (key, count.meaning, count.combine) for key, count in SCHEMA.items()
    ]
