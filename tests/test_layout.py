"""The package layout docs/architecture.md describes: each sub-package of hexsim imports only
the shared modules and the packages before it on the data path, and compensation imports nothing of
hexsim. Read from the source (every import statement, also those inside functions), not from a run."""

from __future__ import annotations

import ast
import pathlib

ROOT = pathlib.Path(__file__).resolve().parents[1]

#: hexsim's packages in data-path order; a module may import its own package and those before it.
ORDER = ["shared", "plant", "control", "engine", "studies", "outputs", "measured", "interfaces", "commands"]
SHARED = {"errors", "tables", "signals", "jitcache"}
COMMANDS = {"cli", "bench", "__init__", "__main__"}
#: hexsim.models (the top-level models/: the MJCF and its builder) is the plant's rigid body: plant/model.py
#: loads it and its builder reads plant/geometry.py, so it stands on the plant's layer.
PLANT_TOO = {"models"}


def _layer(parts: list[str]) -> str:
    """Layer of the hexsim module ``hexsim.<parts>``."""
    head = parts[0] if parts else "__init__"
    if head in SHARED:
        return "shared"
    if head in COMMANDS:
        return "commands"
    if head in PLANT_TOO:
        return "plant"
    assert head in ORDER, f"hexsim.{head} is in no layer of the layout (docs/architecture.md)"
    return head


def _hexsim_imports(path: pathlib.Path) -> list[tuple[int, list[str]]]:
    """(line, module path below hexsim) of each import of a hexsim module in ``path``."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module] + [f"{node.module}.{a.name}" for a in node.names if node.module == "hexsim"]
        else:
            continue
        for name in names:
            parts = name.split(".")
            if parts[0] == "hexsim" and (len(parts) > 1 or node.__class__ is ast.Import):
                found.append((node.lineno, parts[1:]))
    return found


def _modules() -> list[tuple[pathlib.Path, tuple[str, ...]]]:
    """(file, module path below hexsim) of every module of hexsim, models/ (installed as hexsim.models) included."""
    found = [(p, p.relative_to(ROOT / "hexsim").with_suffix("").parts) for p in sorted((ROOT / "hexsim").rglob("*.py"))]
    return found + [(p, ("models", *p.relative_to(ROOT / "models").with_suffix("").parts))
                    for p in sorted((ROOT / "models").rglob("*.py"))]


def test_each_package_imports_only_those_before_it_on_the_data_path():
    wrong = []
    for path, rel in _modules():
        own = ORDER.index(_layer(list(rel)))
        for line, target in _hexsim_imports(path):
            if target and target[0] == "__version__":
                continue
            if ORDER.index(_layer(target)) > own:
                wrong.append(f"{path.relative_to(ROOT)}:{line} imports hexsim.{'.'.join(target)}")
    assert not wrong, "\n".join(wrong)


def test_no_flat_modules_left_outside_the_layout():
    flat = {p.stem for p in (ROOT / "hexsim").glob("*.py")}
    assert flat <= SHARED | COMMANDS, sorted(flat - SHARED - COMMANDS)


def test_compensation_imports_nothing_of_hexsim():
    for path in sorted((ROOT / "compensation").rglob("*.py")):
        assert not _hexsim_imports(path), f"{path.name} imports hexsim"


def test_every_package_is_installed():
    """A sub-package the wheel leaves out imports in the editable checkout and fails from `pip install .`
    (found so: hexsim.measured.reports): pyproject's package list names every folder with an __init__.py."""
    import tomllib

    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    for top in ("hexsim", "compensation"):
        for init in (ROOT / top).rglob("__init__.py"):
            name = ".".join(init.parent.relative_to(ROOT).parts)
            assert name in listed, f"{name} is not in pyproject.toml's [tool.setuptools] packages"


#: hexsim.measured from the bottom up (docs/design.md, "What a change touches"): the vocabulary and the log,
#: the replays, the one optimizer, the scoring layer, then calibration and identification side by side on it,
#: the reports, the validation that composes them. A module imports only modules on floors below its own, or
#: on its own floor those of its own side (:data:`SIDES`).
MEASURED_FLOORS = (
    {"estimates", "statistics", "measurement", "residuals", "box_lsq"},
    {"parameters", "records", "replay", "acceptance_logs"},
    {"fitting", "hexapod_replay", "proof", "flow_balance"},
    {"scoring", "flow_curve", "friction_id", "steady"},
    {"calibration", "acquisition", "curves", "dynamics", "envelope", "form_refit", "null_drift", "candidates",
     "discovery", "identify", "effect_fit"},
    {"reports.calibration", "reports.commissioning", "reports.friction", "reports.validation", "advice", "curve_read"},
    {"validation", "commissioning"},
)
#: The two sides of the floor above scoring: a machine's nominal, and the effects the nominal lacks.
SIDES = ({"calibration", "acquisition", "curves", "dynamics", "envelope", "form_refit", "null_drift"},
         {"candidates", "discovery", "identify", "effect_fit"})


def test_calibration_and_identification_stand_side_by_side_on_scoring():
    floor = {name: i for i, names in enumerate(MEASURED_FLOORS) for name in names}
    side = {name: i for i, names in enumerate(SIDES) for name in names}
    wrong = []
    for path in sorted((ROOT / "hexsim" / "measured").rglob("*.py")):
        name = ".".join(path.relative_to(ROOT / "hexsim" / "measured").with_suffix("").parts)
        if name.split(".")[-1] == "__init__":
            continue
        assert name in floor, f"hexsim.measured.{name} is on no floor of MEASURED_FLOORS: place it"
        for line, target in _hexsim_imports(path):
            if target[:1] != ["measured"] or len(target) < 2:
                continue
            used = ".".join(target[1:3] if target[1] == "reports" else target[1:2])
            if used not in floor:  # an imported name of a module (hexsim.measured.reports: its package)
                continue
            same_side = used in side and side.get(name) == side[used]
            if floor[used] > floor[name] or (floor[used] == floor[name] and not same_side):
                wrong.append(f"hexsim/measured/{name.replace('.', '/')}.py:{line} imports hexsim.measured.{used}")
    assert not wrong, "\n".join(wrong)


#: A module a newcomer reads in one sitting, a function on one screen (issue 54's "done when").
MAX_MODULE_LINES, MAX_FUNCTION_LINES = 600, 60


def test_no_module_over_600_lines_and_no_function_over_60_in_hexsim():
    long = []
    for path in sorted((ROOT / "hexsim").rglob("*.py")):
        text = path.read_text()
        name = path.relative_to(ROOT).as_posix()
        if len(text.splitlines()) > MAX_MODULE_LINES:
            long.append(f"{name}: {len(text.splitlines())} lines")
        for node in ast.walk(ast.parse(text, name)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                size = node.end_lineno - node.lineno + 1
                if size > MAX_FUNCTION_LINES:
                    long.append(f"{name}:{node.lineno} {node.name}: {size} lines")
    assert not long, "\n".join(long)
