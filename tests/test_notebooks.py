"""Every notebook runs top to bottom in a real Jupyter kernel (nbclient + ipykernel), as a reader
would run it, and is committed with its outputs stripped."""

import json
from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient


NOTEBOOKS = sorted((Path(__file__).parents[1] / "notebooks").glob("*.ipynb"))
CELL_TIMEOUT = 900  # [s] one cell; a whole notebook should take under 3 minutes
# The suite runs every notebook in a kernel except 03 (most of its time is compiling four
# programs), which runs with `pytest -m heavy` (docs/development.md).
HEAVY_KERNEL_RUNS = ("03_gradients.ipynb",)
assert set(HEAVY_KERNEL_RUNS) <= {p.name for p in NOTEBOOKS}, "a heavy notebook that is not there"
KERNEL_RUNS = [
    pytest.param(p, marks=pytest.mark.heavy if p.name in HEAVY_KERNEL_RUNS else ())
    for p in NOTEBOOKS
]


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.name for p in NOTEBOOKS])
def test_notebook_is_committed_stripped(path):
    cells = json.loads(path.read_text())["cells"]
    code = [c for c in cells if c["cell_type"] == "code"]
    assert code, "a notebook without code"
    assert all(not c.get("outputs") and c.get("execution_count") is None for c in code), (
        f"{path.name} is committed with outputs: strip them"
    )


@pytest.mark.parametrize("path", KERNEL_RUNS, ids=[p.name for p in NOTEBOOKS])
def test_notebook_runs_in_a_jupyter_kernel(path, tmp_path, monkeypatch):
    # a fresh compilation cache per run: the notebooks are measured with the cache cold
    cache = tmp_path / "jax-cache"
    monkeypatch.setenv("BOGIE_JAX_CACHE_DIR", str(cache))
    monkeypatch.setenv("MPLBACKEND", "module://matplotlib_inline.backend_inline")
    notebook = nbformat.read(path, as_version=4)
    client = NotebookClient(
        notebook,
        timeout=CELL_TIMEOUT,
        kernel_name="python3",
        resources={"metadata": {"path": str(tmp_path)}},
    )
    client.execute()  # raises CellExecutionError naming the cell on any exception
    outputs = [o for c in notebook.cells if c.cell_type == "code" for o in c.get("outputs", [])]
    assert not [o for o in outputs if o.get("output_type") == "error"]
    # figures render as images, not as their text repr
    assert any("image/png" in o.get("data", {}) for o in outputs), "no figure was displayed"
    # the notebook turned the persistent cache on: a second run skips the compiles
    assert cache.is_dir() and any(p.name.endswith("-cache") for p in cache.iterdir())
