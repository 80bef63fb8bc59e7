"""The examples in femshell's docstrings run and print what they show (doctest), so that a
reader who copies one gets what the docstring says."""

import doctest
import importlib
import pkgutil
from pathlib import Path

import pytest

import femshell

ROOT = Path(__file__).resolve().parents[1]
MODULES = ["femshell"] + sorted(m.name for m in pkgutil.walk_packages(femshell.__path__, "femshell."))


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name, monkeypatch):
    monkeypatch.chdir(ROOT)                 # examples name files relative to the repository
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE, report=False,
                             verbose=False)
    assert result.failed == 0, f"{result.failed} of {result.attempted} docstring examples of {name} failed"
