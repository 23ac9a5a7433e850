"""Long calls as a user watches them: the live page served by ``acquire(...,
serve=True)`` and its address shown and kept, progress handed to a callable (and
drawn by tqdm in a notebook), with the results unchanged by watching."""

from __future__ import annotations

import json
import urllib.request

import pandas as pd
import pytest

import gonio
from conftest import CONFIG

INSTRUMENT = CONFIG / "instrument-sim.toml"
PLAN = CONFIG / "plan-in-plane.toml"


def slow_sim(tmp_path, scale: float):
    """The example simulator config at `scale` wall seconds per physical second."""
    p = tmp_path / "slow.toml"
    text = (CONFIG / "sim-example.toml").read_text()
    p.write_text(text.replace("time_scale = 0.0", f"time_scale = {scale}"))
    return p


def test_acquire_serves_the_live_page_and_shows_its_address(tmp_path, capfd):
    pages = {}

    def watch(p: gonio.Progress) -> None:
        # The page answers while the run is measured (the call is still going on).
        if p.url and p.url not in pages:
            with urllib.request.urlopen(p.url, timeout=10) as r:
                pages[p.url] = (r.status, r.read().decode())

    out = tmp_path / "run.gonio"
    run = gonio.acquire(
        INSTRUMENT,
        PLAN,
        out,
        seed=5,
        progress=watch,
        serve=True,
        control=True,
        sim=slow_sim(tmp_path, 0.0005),
    )
    assert run.status == "complete" and run.session["status"] == "complete"
    url = run.live_url
    assert url.startswith("http://127.0.0.1:") and "?token=" in url
    status, html = pages[url]
    assert status == 200 and "<html" in html.lower()
    # Shown once, by the package (where a notebook shows it), with the command's words.
    err = capfd.readouterr().err
    assert err.count(url) == 1
    assert f"gonio: live view at {url} (the token allows Stop and Pause)" in err
    # And the readings are the command's, served or not.
    quiet = gonio.acquire(INSTRUMENT, PLAN, tmp_path / "quiet.gonio", seed=5, progress=False)
    assert quiet.live_url is None
    pd.testing.assert_series_equal(run.readings()["r_mean"], quiet.readings()["r_mean"])


def test_a_bad_serve_address_is_refused_before_the_run_exists(cli, tmp_path):
    out = tmp_path / "x.gonio"
    with pytest.raises(gonio.InputError) as e:
        gonio.acquire(INSTRUMENT, PLAN, out, progress=False, serve="300.1.2.3:0")
    code, line = cli.error(
        "acquire",
        "--instrument",
        INSTRUMENT,
        "--plan",
        PLAN,
        "--out",
        out,
        "--serve",
        "300.1.2.3:0",
    )
    assert (str(e.value), e.value.exit_code) == (line, code) and code == 2
    assert not out.exists()


def test_acquire_and_resume_report_their_steps(tmp_path):
    seen: list[gonio.Progress] = []
    run = gonio.acquire(INSTRUMENT, PLAN, tmp_path / "run.gonio", seed=5, progress=seen.append)
    steps = run.summary["steps"]
    assert seen and {p.stage for p in seen} == {"acquire"} and seen[-1].unit == "steps"
    assert seen[-1].done == seen[-1].total == steps
    assert [p.done for p in seen] == sorted(p.done for p in seen)
    assert any(p.message.startswith("sample: R = ") for p in seen)
    assert all(p.url is None for p in seen)
    # A callable that raises stops the run as Ctrl-C does, with its own exception.

    def fail(p: gonio.Progress) -> None:
        if p.done >= 3:
            raise RuntimeError("enough")

    out = tmp_path / "stopped.gonio"
    with pytest.raises(RuntimeError, match="enough"):
        gonio.acquire(INSTRUMENT, PLAN, out, seed=5, progress=fail, sim=slow_sim(tmp_path, 0.001))
    assert gonio.open_run(out).status == "interrupted"
    seen.clear()
    run = gonio.resume(out, progress=seen.append)
    assert run.status == "complete"
    assert seen[-1].stage == "resume" and seen[-1].done == seen[-1].total == steps
    # The resume counts from the steps already done. (Before the engine starts, the
    # stage may be seen with nothing done and no total yet: a 50 ms poll of a loaded
    # machine can land there.)
    counted = [p for p in seen if p.total is not None]
    assert counted[0].done > 0
    assert all(p.done == 0 for p in seen if p.total is None)


def test_micro_with_progress_is_the_same_table(cli, tmp_path):
    surface = CONFIG / "micro-gaussian-gold.toml"
    out = tmp_path / "m.csv"
    want = cli.json(
        "micro", surface, "--grid", "15,45", "--rays", "3000", "--seed", "7", "--out", out
    )
    seen: list[gonio.Progress] = []
    got = gonio.micro.simulate(surface, grid=(15, 45), rays=3000, seed=7, progress=seen.append)
    pd.testing.assert_frame_equal(got, pd.read_csv(out), check_exact=True, check_dtype=False)
    got.attrs["micro"].pop("seconds")
    want.pop("seconds")
    assert got.attrs["micro"] == {k: v for k, v in want.items() if k != "out"}
    incidences = (
        got.attrs["gonio"]["grid"]["theta_i"]["n"] * got.attrs["gonio"]["grid"]["phi_i"]["n"]
    )
    assert seen[-1] == gonio.Progress("trace", incidences, incidences, "incidences", "", None)
    plain = gonio.micro.simulate(surface, grid=(15, 45), rays=3000, seed=7, progress=False)
    pd.testing.assert_frame_equal(got, plain, check_exact=True)


def test_fit_reports_its_stage(runs):
    seen: list[gonio.Progress] = []
    with_bar = gonio.fit(runs["py"], lobes=1, progress=seen.append)
    assert seen and seen[-1].stage == "fit" and seen[-1].total is None
    assert with_bar.model_file == gonio.fit(runs["py"], lobes=1, progress=False).model_file


nbformat = pytest.importorskip("nbformat")
nbclient = pytest.importorskip("nbclient")

NOTEBOOK_CELL = """
import gonio
run = gonio.acquire({instrument!r}, {plan!r}, {out!r}, seed=5, serve=True)
print("URL", run.live_url)
fit = gonio.fit(run, lobes=1)
"""


def test_in_a_notebook_a_tqdm_bar_and_the_address(tmp_path):
    pytest.importorskip("tqdm")
    from test_notebook import kernelspec

    jupyter = kernelspec(tmp_path / "jupyter")
    cell = NOTEBOOK_CELL.format(
        instrument=str(INSTRUMENT), plan=str(PLAN), out=str(tmp_path / "nb.gonio")
    )
    nb = nbformat.v4.new_notebook()
    nb.cells.append(nbformat.v4.new_code_cell(cell))
    mp = pytest.MonkeyPatch()
    mp.setenv("JUPYTER_PATH", str(jupyter))
    try:
        nbclient.NotebookClient(nb, timeout=300, kernel_name="python3").execute()
    finally:
        mp.undo()
    outputs = nb.cells[0].outputs
    stderr = "".join(o.text for o in outputs if o.output_type == "stream" and o.name == "stderr")
    stdout = "".join(o.text for o in outputs if o.output_type == "stream" and o.name == "stdout")
    shown = [o.data for o in outputs if o.output_type == "display_data"]
    url = stdout.split("URL ", 1)[1].split()[0]
    assert url.startswith("http://127.0.0.1:")
    # The address as a link, with the command's words as its text.
    link = [d for d in shown if url in d.get("text/plain", "")]
    assert len(link) == 1 and f'href="{url}"' in link[0]["text/html"]
    # tqdm's bars: the run's steps to the end (its text bar without ipywidgets, else
    # its widget), and the fit's time.
    run = json.dumps(stderr) + json.dumps(shown)
    steps = gonio.open_run(tmp_path / "nb.gonio").summary["steps"]
    assert f"{steps}/{steps}" in run and "acquire" in run and "fit" in run
