"""Dependencies flow one way (docs/architecture.md): a lower layer never imports
a higher one. Read from the sources' import statements (no bpy needed)."""
import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LAYERS = ("warp", "cli", "measure", "settings", "guard", "scene", "gpu", "render", "ui")
"""addon/ packages (and the plain modules addon/settings.py, addon/guard.py) from the bottom up."""
ENTRY_POINTS = {Path("addon/warp/__main__.py"): {"cli"}}
"""Programs, never imported by their layer: ``python -m addon.warp`` runs the CLI above it."""
PLAIN = {"warp", "settings", "guard"}
ALLOWED = {
    "warp": {"warp"},
    "cli": {"warp", "cli"},
    "measure": {"warp", "measure"},
    "settings": {"warp", "settings"},
    "guard": {"warp", "guard"},
    "scene": PLAIN | {"scene"},
    "gpu": PLAIN | {"scene", "gpu"},
    "render": PLAIN | {"scene", "gpu", "render"},
    "ui": set(LAYERS),
}


def _layer_of(module_parts: list) -> str:
    """'addon.<layer>...' -> layer."""
    return module_parts[1].removesuffix(".py") if len(module_parts) > 1 else ""


def _imports(path: Path):
    """(line, absolute dotted module within the checkout) of every relative import."""
    package = list(path.relative_to(ROOT).with_suffix("").parts[:-1])
    tree = ast.parse(path.read_text(encoding="utf-8"))
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level > 0:
            base = package[:len(package) - (node.level - 1)]
            target = base + (node.module.split(".") if node.module else [])
            names = [a.name for a in node.names]
            yield node.lineno, target, names


def _sources(layer: str):
    if layer in ("settings", "guard"):
        return [ROOT / "addon" / f"{layer}.py"]
    return sorted((ROOT / "addon" / layer).rglob("*.py"))


@pytest.mark.parametrize("layer", LAYERS)
def test_no_layer_imports_a_higher_one(layer):
    bad = []
    for path in _sources(layer):
        for line, target, names in _imports(path):
            if target[:1] != ["addon"]:
                continue
            # "from .. import x" inside addon/ names sub-packages
            targets = [target + [n] for n in names] if len(target) == 1 else [target]
            for t in targets:
                if _layer_of(t) not in ALLOWED[layer] | ENTRY_POINTS.get(path.relative_to(ROOT), set()):
                    bad.append(f"{path.relative_to(ROOT)}:{line} imports {'.'.join(t)}")
    assert bad == []


def test_preferences_and_properties_do_not_import_each_other():
    def imported(name):
        path = ROOT / "addon" / "ui" / f"{name}.py"
        out = set()
        for _line, target, names in _imports(path):
            out.add(".".join(target))
            out.update(".".join(target + [n]) for n in names)
        return out
    # preferences builds on the scene settings' definitions; properties reads the
    # registered preferences through the package (addon.ui.addon_preferences), not the module
    assert "addon.ui.preferences" not in imported("properties")


def test_operators_live_in_the_ui_package():
    assert not (ROOT / "operators").exists()
    assert (ROOT / "addon" / "ui" / "operators" / "__init__.py").is_file()
