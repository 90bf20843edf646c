"""One parser of ``--methods`` (issue 45): every study's ``parse_methods`` is a rule given to
:func:`ikbench.methods.registry.parse_names`, so splitting, de-duplication and refusals read
the same in ``compare``, ``bench``, ``cartesian`` and ``ik``."""

from __future__ import annotations

import ast
import inspect

import pytest

from ikbench.core.errors import InputError
from ikbench.methods.registry import parse_names
from ikbench.studies import bench, cartesian, compare, ik

PARSERS = {"compare": compare.parse_methods, "bench": bench.parse_methods,
           "cartesian": cartesian.parse_methods, "ik": ik.parse_methods}


@pytest.mark.parametrize("study", PARSERS)
def test_every_study_refuses_alike(study):
    parse = PARSERS[study]
    with pytest.raises(InputError, match=r"^--methods: ' , ' names no method; "):
        parse(" , ")
    with pytest.raises(InputError, match=r"^--methods: unknown (single-pose IK )?method "
                                         r"'nope'; (available|registered): .*"
                                         r"\(ikbench methods lists them all\)$"):
        parse("ours-lm,nope")
    with pytest.raises(InputError, match=r"unknown (single-pose IK )?methods 'no1', 'no2'"):
        parse("no1,no2")


@pytest.mark.parametrize("study", PARSERS)
def test_names_split_trimmed_and_deduplicated(study):
    assert PARSERS[study](" ours-lm ,ours-lm,") == ["ours-lm"]
    assert PARSERS[study](["ours-lm", "ours-lm"]) == ["ours-lm"]


def test_rules_differ_only_where_the_studies_do():
    # cartesian's own rule (goal frames) is tested through the CLI in test_cartesian.py
    assert bench.parse_methods("ours") == ["ours"]
    with pytest.raises(InputError, match="unknown single-pose IK method 'ours'"):
        ik.parse_methods("ours")
    assert cartesian.parse_methods(None) == list(cartesian.frame_methods())
    assert parse_names("ours", option="--method") == ["ours"]


def test_no_study_splits_names_itself():
    """The parsers of the studies hold a rule and a call, no parsing of their own."""
    for study, parse in PARSERS.items():
        tree = ast.parse(inspect.getsource(parse))
        calls = {n.func.id for n in ast.walk(tree)
                 if isinstance(n, ast.Call) and isinstance(n.func, ast.Name)}
        assert "parse_names" in calls, study
        assert not any(isinstance(n, ast.Attribute) and n.attr == "split"
                       for n in ast.walk(tree)), study
