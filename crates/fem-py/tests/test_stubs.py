"""The type stubs name every exported symbol, and nothing that does not exist."""

import ast
import inspect
from pathlib import Path

import pyfem2d
from pyfem2d import _native

STUB = Path(pyfem2d.__file__).with_name("_native.pyi")


def stub_names():
    tree = ast.parse(STUB.read_text())
    top, classes = set(), {}
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            top.add(node.name)
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            top.add(node.target.id)
        elif isinstance(node, ast.Assign):
            top.update(t.id for t in node.targets if isinstance(t, ast.Name))
        if isinstance(node, ast.ClassDef):
            classes[node.name] = {
                n.name for n in node.body if isinstance(n, ast.FunctionDef)
            }
    return top, classes


def public(obj):
    return {n for n in dir(obj) if not n.startswith("__")}


def test_every_module_symbol_is_in_the_stub():
    top, _ = stub_names()
    exported = {n for n in dir(_native) if not (n.startswith("__") and n != "__version__")}
    missing = exported - top
    assert not missing, f"not in _native.pyi: {sorted(missing)}"
    # And the stub names nothing the module lacks (the type aliases aside).
    aliases = {"Overrides", "F64Array1", "F64Array2", "I64Array1", "I64Array2"}
    extra = top - exported - aliases
    assert not extra, f"in _native.pyi but not in the module: {sorted(extra)}"


def test_every_method_and_property_is_in_the_stub():
    _, classes = stub_names()
    for name in ("Simulation", "Snapshot", "StepReport"):
        cls = getattr(_native, name)
        have = public(cls)
        stubbed = classes[name]
        assert have - stubbed == set(), f"{name}: not in the stub: {sorted(have - stubbed)}"
        assert stubbed - have - {"__init__"} == set(), f"{name}: stub only: {sorted(stubbed - have)}"


def test_the_package_exports_what_it_lists():
    for name in pyfem2d.__all__:
        assert hasattr(pyfem2d, name), name
    assert (Path(pyfem2d.__file__).parent / "py.typed").exists()


def test_stub_signatures_match_the_runtime():
    # The keyword names of each function agree with the extension's own signatures.
    tree = ast.parse(STUB.read_text())
    for node in tree.body:
        if isinstance(node, ast.FunctionDef) and not node.name.startswith("_"):
            runtime = inspect.signature(getattr(_native, node.name))
            stub = [a.arg for a in node.args.args + node.args.kwonlyargs]
            assert list(runtime.parameters) == stub, node.name
