"""examples/quickstart.ipynb runs from end to end, in a kernel of this interpreter,
from a working directory outside the repository, and its cells show what they say."""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import pytest

nbformat = pytest.importorskip("nbformat")
nbclient = pytest.importorskip("nbclient")

ROOT = Path(__file__).resolve().parents[3]
NOTEBOOK = ROOT / "examples" / "quickstart.ipynb"

#: Appended to the notebook in memory: which interpreter the kernel is.
PROBE = "import sys\nprint(sys.prefix)\nprint(sys.executable)"


def by_tag(nb, tag):
    """The one code cell tagged ``tag``."""
    cells = [c for c in nb.cells if tag in c.get("metadata", {}).get("tags", [])]
    assert len(cells) == 1, f"{len(cells)} cells tagged {tag!r}"
    return cells[0]


def text(cell):
    """Everything a cell printed or displayed as text."""
    parts = []
    for out in cell.outputs:
        if out.output_type == "stream":
            parts.append(out.text)
        elif "data" in out:
            parts.append(out.data.get("text/plain", ""))
    return "\n".join(parts)


def mime_types(cell):
    return [m for out in cell.outputs if "data" in out for m in out.data]


def kernelspec(root):
    """A ``python3`` kernelspec under ``root`` that starts this interpreter. Found
    first through ``JUPYTER_PATH``, it keeps a user's own ``python3`` kernelspec
    (which may name another interpreter) out of the test."""
    spec = root / "kernels" / "python3"
    spec.mkdir(parents=True)
    argv = [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"]
    kernel = {
        "argv": argv,
        "display_name": "Python 3 (gonio tests)",
        "language": "python",
    }
    (spec / "kernel.json").write_text(json.dumps(kernel))
    return root


@pytest.fixture(scope="module")
def executed(tmp_path_factory):
    """The notebook executed with nbclient, its working directory a temporary one
    (the notebook finds the repository through ``GONIO_ROOT``)."""
    cwd = tmp_path_factory.mktemp("notebook-cwd")
    jupyter = kernelspec(tmp_path_factory.mktemp("jupyter"))
    nb = nbformat.read(NOTEBOOK, as_version=4)
    nb.cells.append(nbformat.v4.new_code_cell(PROBE, id="probe"))
    mp = pytest.MonkeyPatch()
    mp.setenv("GONIO_ROOT", str(ROOT))
    mp.setenv("JUPYTER_PATH", str(jupyter))
    # The kernel is headless whatever the environment says.
    mp.delenv("MPLBACKEND", raising=False)
    try:
        client = nbclient.NotebookClient(
            nb,
            timeout=600,
            kernel_name="python3",
            resources={"metadata": {"path": str(cwd)}},
        )
        client.execute()
    finally:
        mp.undo()
    return nb, cwd


def test_saved_without_outputs():
    nb = nbformat.read(NOTEBOOK, as_version=4)
    nbformat.validate(nb)
    for cell in nb.cells:
        if cell.cell_type == "code":
            assert cell.outputs == [], cell.id
            assert cell.execution_count is None, cell.id


def test_kernel_is_this_interpreter(executed):
    nb, _ = executed
    prefix, executable = text(nb.cells[-1]).split()
    assert Path(prefix) == Path(sys.prefix)
    assert Path(executable) == Path(sys.executable)


def test_runs_without_errors(executed):
    nb, cwd = executed
    for cell in nb.cells:
        if cell.cell_type != "code":
            continue
        assert cell.execution_count is not None, cell.id
        for out in cell.outputs:
            assert out.output_type != "error", (
                cell.id,
                out.get("ename"),
                out.get("evalue"),
            )
    # Nothing is left in the working directory: the run went to a temporary one.
    assert list(cwd.iterdir()) == []


def test_cells_show_what_they_say(executed):
    nb, _ = executed
    assert "complete" in text(by_tag(nb, "acquire"))
    assert "isotropic hemisphere" in text(by_tag(nb, "meta"))
    readings = by_tag(nb, "readings")
    assert "'sample': 618" in text(readings)
    assert "text/html" in mime_types(readings)
    assert "618 samples" in text(by_tag(nb, "reduce"))
    check = text(by_tag(nb, "check"))
    for measure in ("P_r", "P_ec", "P_i", "P_s^(1)", "P_s^(5)", "P_s^(10)"):
        assert measure in check
    fit = text(by_tag(nb, "fit"))
    for name in ("rho_d", "lobe 3", "Cx", "Cz", "std_err"):
        assert name in fit
    report = text(by_tag(nb, "report"))
    assert "channel value" in report
    assert "reduced χ²" in report
    for tag in ("polar", "hemisphere"):
        assert mime_types(by_tag(nb, tag)).count("image/png") == 1, tag
    evaluated = text(by_tag(nb, "eval"))
    assert "(90, 180)" in evaluated
    # The albedo summed over the grid is the model's own, to the grid's precision.
    grid, exact = map(float, re.search(r"grid ([\d.]+), model.albedo ([\d.]+)", evaluated).groups())
    assert grid == pytest.approx(exact, rel=1e-3)
