"""The package roots' public names: each imports, says how to use it, and importing the root
stays cheap (no torch, no simulator, not even the submodules until a name is asked for)."""

import importlib
import json
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
ROOTS = ("conceptfusion", "agents")


@pytest.mark.parametrize("root, name", [(r, n) for r in ROOTS for n in importlib.import_module(r).__all__])
def test_every_public_name_imports_with_an_example(root, name):
    obj = getattr(importlib.import_module(root), name)
    assert obj.__module__.startswith(root + ".")
    assert f"from {root} import" in (obj.__doc__ or ""), f"{root}.{name}: expected a docstring with an example importing it from {root}"


def test_the_public_names_are_the_ones_documented():
    import agents
    import conceptfusion

    assert set(conceptfusion.__all__) == {"RGBDFrame", "load_map", "make_encoder", "make_mapper", "register_encoder", "save_map"}
    assert {"register_agent", "make_agent", "make_mapper", "AgentSpec", "Option"} == set(agents.__all__)
    assert set(conceptfusion.__all__) <= set(dir(conceptfusion))


def test_an_unknown_name_is_an_attribute_error_naming_the_public_ones():
    import conceptfusion

    with pytest.raises(AttributeError, match=r"no attribute 'registr_encoder' \(public names: RGBDFrame, load_map"):
        conceptfusion.registr_encoder  # noqa: B018
    from conceptfusion import map as submodule  # submodules still import as before

    assert submodule.__name__ == "conceptfusion.map"


@pytest.mark.parametrize("statement, absent", [
    ("import conceptfusion, agents", ["torch", "mujoco", "numpy", "conceptfusion.perception", "agents.registry"]),
    ("from conceptfusion import register_encoder, make_encoder, RGBDFrame", ["torch", "mujoco", "transformers", "onnxruntime"]),
])
def test_importing_the_root_loads_nothing_heavy(statement, absent):
    code = f"import json, sys; {statement}; print(json.dumps(sorted(set({absent!r}) & set(sys.modules))))"
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, check=True).stdout
    assert json.loads(out) == []
