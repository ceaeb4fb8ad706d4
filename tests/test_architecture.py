"""The package's shape: one-way imports along the layer order, no import cycle, no private names
used across packages by tests and benchmarks, and no oversized file without a stated reason.

Imports are read from the source with `ast` (function-body imports included), so a deferred
import that dodges a cycle at run time is still an edge here.
"""

import ast
import pathlib
import re
import subprocess
import sys

import pytest


ROOT = pathlib.Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "bogie_jax"

# params -> contact/track -> model -> simulate -> measure -> cost
#   -> gradients / identify / sensitivity -> monitor -> io / plot / cli  (README, issue "One house")
LAYERS = {
    "_precision": 0,
    "_version": 0,
    "_validation": 0,
    "_householder": 0,  # a least-squares / square linear solver in plain XLA operations
    "params": 0,
    "qmc": 0,  # quasi-Monte Carlo points (multistart designs, Sobol' indices)
    "runtime": 0,  # solve settings, batch runners, program store, compilation cache
    "contact": 1,
    "track": 1,
    "model": 2,
    "simulation": 3,
    "small_motion": 3.2,  # the linearised model's response, exactly discretised
    "hunting": 3.5,  # the nonlinear critical speed: a speed ramp-down of simulations
    "measure": 4,
    "cost": 5,
    "gradients": 6,
    "identify": 6,
    "sensitivity": 6,
    "monitor": 7,
    "io": 8,
    "plot": 8,
    "fleet": 8.5,  # reads measurement and verdicts files (io); under the command line
    "cli": 9,
    "__init__": 10,  # the top-level re-exports
}
MAX_LINES = 400


def _module_name(path: pathlib.Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _imported_modules(path: pathlib.Path, text: str | None = None):
    """`(module, names, line)` of each `bogie_jax` import in `path` (its source, or `text`)."""
    here = _module_name(path).split(".")
    package = here if path.name == "__init__.py" else here[:-1]
    for node in ast.walk(ast.parse(path.read_text() if text is None else text)):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[: len(package) - (node.level - 1)]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.startswith("bogie_jax"):
                yield target, [a.name for a in node.names], node.lineno
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("bogie_jax"):
                    yield alias.name, [], node.lineno


def _top(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def _package_files():
    return sorted(PACKAGE.rglob("*.py"))


def test_every_top_level_module_has_a_layer():
    tops = {_top(_module_name(p)) for p in _package_files()}
    assert not tops - set(LAYERS), (
        f"modules without a layer in LAYERS: {sorted(tops - set(LAYERS))}"
    )


def test_imports_follow_the_layer_order():
    wrong = []
    for path in _package_files():
        source = _top(_module_name(path))
        for target, _, line in _imported_modules(path):
            dest = _top(target)
            if dest != source and LAYERS.get(dest, -1) > LAYERS[source]:
                wrong.append(f"{path.relative_to(ROOT)}:{line} imports {target} (layer {dest})")
    assert not wrong, "imports against the layer order:\n" + "\n".join(wrong)


def test_no_import_cycle_between_top_level_modules():
    graph: dict[str, set[str]] = {}
    for path in _package_files():
        source = _top(_module_name(path))
        for target, _, _ in _imported_modules(path):
            if _top(target) != source:
                graph.setdefault(source, set()).add(_top(target))
    cycles = []

    def visit(node, stack):
        for nxt in sorted(graph.get(node, ())):
            if nxt in stack:
                cycles.append(" -> ".join([*stack[stack.index(nxt) :], nxt]))
            elif len(stack) < len(LAYERS):
                visit(nxt, [*stack, nxt])

    for start in sorted(graph):
        visit(start, [start])
    assert not cycles, "import cycles:\n" + "\n".join(sorted(set(cycles)))


def test_the_checker_resolves_relative_imports():
    """A `model` module importing `..cost` is an edge model -> cost, against the order."""
    fake = PACKAGE / "model" / "_x.py"
    edges = list(_imported_modules(fake, "def f():\n    from ..cost import Objective\n"))
    assert edges == [("bogie_jax.cost", ["Objective"], 2)]
    assert LAYERS[_top(edges[0][0])] > LAYERS[_top(_module_name(fake))]


def _private_uses(path: pathlib.Path):
    """`bogie_jax` names used by `path` (a test or benchmark) that are private to a package."""
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("bogie_jax"):
            modules = node.module.split(".")
            private = [m for m in modules if m.startswith("_")]
            names = [a.name for a in node.names if a.name.startswith("_")]
            if private or names:
                yield f"{path.relative_to(ROOT)}:{node.lineno} from {node.module} import " + (
                    ", ".join(a.name for a in node.names)
                )
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("bogie_jax") and "._" in alias.name:
                    yield f"{path.relative_to(ROOT)}:{node.lineno} import {alias.name}"


@pytest.mark.parametrize("folder", ["tests", "benchmarks"])
def test_tests_and_benchmarks_use_only_public_names(folder):
    files = [p for p in sorted((ROOT / folder).rglob("*.py")) if p.name != "test_architecture.py"]
    uses = [u for p in files for u in _private_uses(p)]
    assert not uses, "private names of bogie_jax used:\n" + "\n".join(uses)


def test_no_file_over_400_lines_without_a_reason():
    """A longer file says why in a comment among its first lines (`# long: ...`)."""
    files = [
        *_package_files(),
        *(ROOT / "tests").rglob("*.py"),
        *(ROOT / "benchmarks").glob("*.py"),
    ]
    long = []
    for path in files:
        lines = path.read_text().splitlines()
        if len(lines) > MAX_LINES and not any(line.startswith("# long:") for line in lines[:15]):
            long.append(f"{path.relative_to(ROOT)} ({len(lines)} lines)")
    assert not long, f"files over {MAX_LINES} lines without a '# long:' reason:\n" + "\n".join(long)


def test_top_level_re_exports_resolve_and_import_no_jax():
    """`bogie_jax` offers what a notebook needs, and importing it loads no JAX (the command
    line sets up devices first). An exported function is never shadowed by a submodule of the
    same name (importing `bogie_jax.x` sets the package attribute `x` to the module)."""
    code = (
        "import sys, bogie_jax as bj; assert 'jax' not in sys.modules; "
        "[getattr(bj, n) for n in bj.__all__]; import bogie_jax.cost; "
        "assert callable(bj.simulate) and callable(bj.fit), (bj.simulate, bj.fit); "
        "import bogie_jax.monitor, types; assert isinstance(bj.monitor, types.ModuleType); "
        "assert not callable(bj.monitor) and callable(bj.monitor.monitor); "
        "print(sorted(bj.__all__))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    names = set(eval(out.stdout))
    assert {"simulate", "fit", "fit_multistart", "make_objective", "judge", "trend"} <= names
    assert "MonitorOptions" in names and "monitor" not in names  # `bj.monitor`: the package


def test_a_source_checkout_that_is_not_installed_still_imports():
    """Run from a checkout on `sys.path` without the package's metadata (no `pip install`),
    `bogie_jax` imports and says its version is unknown instead of raising."""
    code = (
        "import importlib.metadata as md\n"
        "def missing(name): raise md.PackageNotFoundError(name)\n"
        "md.version = missing\n"
        "import bogie_jax\n"
        "print(bogie_jax.__version__)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "unknown (not installed)"


# --- the house a newcomer reads: README sizes and result files ---

README_MAX_LINES = 250
BENCHMARKS_README_MAX_LINES = 300
RESULTS = ROOT / "benchmarks" / "results"
PERIOD_WORDS = {"before", "after", "now", "old", "new", "latest", "today", "yesterday"}


def names_a_work_period(stem: str) -> bool:
    """Whether a result's name names a work period or a moment: `s18`, `session13`, `sprint2`,
    `before`, `after`, `now`, ... or a date (`2026-11-26`)."""
    for token in stem.replace(".", "_").split("_"):
        if token.count("-") == 2 and token.replace("-", "").isdigit():
            return True
        for word in token.lower().split("-"):
            if word in PERIOD_WORDS or (word[:1] == "s" and word[1:].isdigit()):
                return True
            if word.startswith(("session", "sprint")):
                return True
    return False


def test_readmes_fit_their_line_budgets():
    """The README is for users and the benchmarks README an index; history goes to docs/."""
    for path, limit in (
        (ROOT / "README.md", README_MAX_LINES),
        (ROOT / "benchmarks" / "README.md", BENCHMARKS_README_MAX_LINES),
    ):
        n = len(path.read_text().splitlines())
        assert n <= limit, f"{path.relative_to(ROOT)} has {n} lines, more than {limit}"


def _result_files():
    return sorted(p for p in RESULTS.rglob("*") if p.is_file() and p.suffix != ".tmp")


def test_result_files_sit_in_their_benchmarks_folder_and_name_no_work_period():
    """`results/<benchmark>/<what it measures>.<ext>`: the folder is a benchmark script's name,
    and no part of the path names a work period or a moment (`compile_s18_before`)."""
    scripts = {p.stem for p in (ROOT / "benchmarks").glob("*.py") if not p.stem.startswith("_")}
    bad = []
    for path in _result_files():
        parts = path.relative_to(RESULTS).parts
        stem = parts[-1].split(".")[0]
        if len(parts) != 2 or parts[0] not in scripts or names_a_work_period(stem):
            bad.append(str(path.relative_to(ROOT)))
    assert not bad, "result files outside results/<benchmark>/ or named after a period:\n" + (
        "\n".join(bad)
    )


def test_every_result_file_is_named_in_the_benchmarks_readme_with_commit_and_date():
    """Each current result is listed in `benchmarks/README.md`, and its JSON and markdown say
    which commit measured it and when."""
    readme = (ROOT / "benchmarks" / "README.md").read_text()
    missing, unstamped = [], []
    for path in _result_files():
        name = f"{path.parent.name}/{path.name.split('.')[0]}"
        if name not in readme:
            missing.append(name)
        if path.suffix in (".json", ".md"):
            text = path.read_text()
            keys = ('"commit"', '"date"') if path.suffix == ".json" else ("commit", "20")
            if not all(k in text for k in keys):
                unstamped.append(str(path.relative_to(ROOT)))
    assert not missing, "result files not named in benchmarks/README.md: " + ", ".join(missing)
    assert not unstamped, "results without commit and date: " + ", ".join(unstamped)


def test_the_work_period_rule_catches_the_old_names():
    for name in ("compile_s18_before", "compile_session13", "compile_now", "detection_2026-11-26"):
        assert names_a_work_period(name), name
    for name in (
        "two_8s_runs",
        "cold_and_warm",
        "one_vs_many_lanes_cpu",
        "multistart_vs_annealing",
    ):
        assert not names_a_work_period(name), name


MONITOR_MAX_LINES = 60  # lines of a function in monitor/, its docstring included
MONITOR_MAX_PARAMETERS = 8  # `self` and `cls` not counted


def test_monitor_functions_are_short_steps_with_few_parameters():
    """`bogie_jax/monitor/` stays a pipeline a reader follows (issue 52): no function or method
    longer than 60 lines or with more than 8 parameters."""
    over = []
    for path in sorted((PACKAGE / "monitor").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if not isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                continue
            a = node.args
            names = [
                x.arg for x in (*a.posonlyargs, *a.args, *a.kwonlyargs, a.vararg, a.kwarg) if x
            ]
            n_params = len([n for n in names if n not in ("self", "cls")])
            n_lines = node.end_lineno - node.lineno + 1
            if n_lines > MONITOR_MAX_LINES or n_params > MONITOR_MAX_PARAMETERS:
                where = f"{path.relative_to(ROOT)}:{node.lineno} {node.name}"
                over.append(f"{where}: {n_lines} lines, {n_params} parameters")
    assert not over, "monitor/ functions over the limits:\n" + "\n".join(over)


def test_monitor_and_identify_docstrings_hold_no_dated_notes():
    """A docstring of `monitor/` or `identify/` says what a thing is and does; dated
    measurements go to docs/history.md (issue 52)."""
    date = re.compile(r"\b20\d\d-[01]\d-[0-3]\d\b")
    dated = [
        f"{path.relative_to(ROOT)}:{n}"
        for folder in ("monitor", "identify")
        for path in sorted((PACKAGE / folder).glob("*.py"))
        for n, line in enumerate(path.read_text().splitlines(), start=1)
        if date.search(line)
    ]
    assert not dated, "dated notes in the source:\n" + "\n".join(dated)
