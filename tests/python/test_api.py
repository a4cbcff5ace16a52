"""The typed API: the stub (python/feedid/__init__.pyi) declares what the module has, with the same parameters, and
every public function and class has a docstring with an example that runs (doctest, with the outputs it shows)."""

import ast
import doctest
import inspect
import pathlib

import numpy as np
import pytest

import feedid
import feedid.fleet
from conftest import EMPS, SOURCE_DIR

STUB = SOURCE_DIR / "python" / "feedid" / "__init__.pyi"


def stub_declarations():
    tree = ast.parse(STUB.read_text())
    functions, classes = {}, {}
    for node in tree.body:
        if isinstance(node, ast.FunctionDef):
            functions[node.name] = node
        elif isinstance(node, ast.ClassDef):
            members = {}
            for item in node.body:
                if isinstance(item, ast.FunctionDef):
                    members.setdefault(item.name, item)
                elif isinstance(item, ast.AnnAssign):
                    members[item.target.id] = item
            classes[node.name] = members
    return functions, classes


def parameters(node):
    arguments = node.args
    names = [a.arg for a in arguments.posonlyargs + arguments.args + arguments.kwonlyargs]
    return [name for name in names if name != "self"]


def public_classes():
    return {name: value for name, value in vars(feedid).items()
            if inspect.isclass(value) and not name.startswith("_") and value.__module__.startswith("feedid")}


def test_the_stub_declares_every_public_name_with_its_parameters():
    functions, classes = stub_declarations()
    for name in feedid.__all__:
        assert name in functions or name in classes or name in ("__version__", "ROLES"), name
    for name, function in vars(feedid).items():
        if inspect.isfunction(function) and not name.startswith("_"):
            assert list(inspect.signature(function).parameters) == parameters(functions[name]), name
    for name, cls in public_classes().items():
        if issubclass(cls, Exception):
            continue
        assert name in classes, name
        runtime = {member for member in dir(cls) if not member.startswith("_")}
        declared = {member for member in classes[name] if not member.startswith("_")}
        assert runtime == declared, (name, runtime ^ declared)
    for name in ("from_arrays", "from_pandas"):
        assert list(inspect.signature(getattr(feedid.Trace, name)).parameters) == parameters(classes["Trace"][name])


def test_every_public_function_and_class_has_a_documented_example():
    documented = [f for n, f in vars(feedid).items() if inspect.isfunction(f) and not n.startswith("_")]
    documented += [c for c in public_classes().values()]
    documented += [feedid.Trace.from_arrays, feedid.Trace.from_pandas, feedid.Trace.to_pandas,
                   feedid.Result.to_pandas, feedid.fleet.identify_file, feedid.fleet.identify_many]
    records = {"TraceSummary", "PreprocessReport", "SelectionReport", "Step1Report", "RlsReport", "LogLinearStribeck",
               "NonlinearFitReport", "StribeckReport", "FrictionCurvePoints", "FrictionCurveReport",
               "FrictionOnlyReport", "ValidationMetrics", "SystematicReport",
               "SystematicVariant"}  # the Result's and Simulation's records: units, no example
    for item in documented:
        text = inspect.getdoc(item) or ""
        if getattr(item, "__name__", "") in records:
            assert "[" in text, item  # their units
        else:
            assert "Example" in text and ">>>" in text, item


def test_the_examples_run(folder):
    if not EMPS.exists():
        pytest.skip(f"{EMPS} not found")
    globs = {"feedid": feedid, "np": np, "EMPS": str(EMPS), "DATABASE": str(folder / "examples.db")}
    finder = doctest.DocTestFinder(exclude_empty=True)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    objects = [feedid, feedid.fleet, feedid.InputError] + list(public_classes().values())
    objects += [feedid.Trace.from_arrays, feedid.Trace.from_pandas, feedid.Trace.to_pandas, feedid.Result.to_pandas]
    seen = set()
    for item in objects:
        for test in finder.find(item, getattr(item, "__name__", repr(item)), module=False, globs=dict(globs)):
            if test.docstring in seen or not test.examples:  # a class is found as feedid.X and as X
                continue
            seen.add(test.docstring)
            runner.run(test)
    assert runner.failures == 0, f"{runner.failures} docstring examples failed (see the output above)"
    assert len(seen) >= 15
