"""gonio.batch on a real Dask cluster: LocalCluster(processes=True) on 127.0.0.1.
Every output is held against the ``gonio`` command run on the same input, byte
for byte where the command writes a file."""

from __future__ import annotations

import hashlib
import json
import os
import pathlib
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from typing import Any

import pandas as pd
import pytest

import gonio
from conftest import CONFIG, ROOT, Cli
from gonio import batch

distributed = pytest.importorskip("distributed")

SAWTOOTH = CONFIG / "micro-sawtooth-deyoung.toml"
SEG = batch.SEGMENT_RAYS


def cluster(n: int) -> Any:
    return distributed.LocalCluster(
        n_workers=n,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address="127.0.0.1:0",
        silence_logs=40,
    )


@pytest.fixture(scope="module")
def client2() -> Iterator[Any]:
    with cluster(2) as c, distributed.Client(c) as cl:
        yield cl


@pytest.fixture(scope="module")
def archive(tmp_path_factory: pytest.TempPathFactory, cli: Cli) -> pathlib.Path:
    """Hemisphere runs of three seeds, in-plane runs of two, and a damaged copy."""
    d = tmp_path_factory.mktemp("archive")
    for seed in (3, 4, 6):
        cli.acquire("plan-hemisphere.toml", d / f"h{seed}.gonio", seed)
    for seed in (5, 7):
        cli.acquire("plan-in-plane.toml", d / f"p{seed}.gonio", seed)
    data = (d / "h3.gonio").read_bytes()
    (d / "bad").mkdir()
    (d / "bad" / "damaged.gonio").write_bytes(data[:8192])
    return d


def digests(d: pathlib.Path) -> dict[str, str]:
    """Name → SHA-256 of every file below ``d``."""
    return {
        str(p.relative_to(d)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(d.rglob("*"))
        if p.is_file()
    }


def cli_json(cli: Cli, *args: Any) -> Any:
    drop = {"out", "seconds"}
    return batch._common.strip(cli.json(*args), frozenset(drop))


def test_reprocess_gives_the_commands_numbers_and_a_damaged_run_its_row(
    archive: pathlib.Path, client2: Any, cli: Cli, tmp_path: pathlib.Path
) -> None:
    runs = sorted(str(p) for p in archive.glob("h*.gonio")) + [
        str(archive / "bad" / "damaged.gonio"),
        str(archive / "bad" / "missing.gonio"),
    ]
    before = digests(archive)
    out = tmp_path / "out"
    df = batch.reprocess(runs, out, client2, steps=("reduce", "check", "fit"), lobes=2)
    assert list(df["run"]) == runs
    assert list(df["status"]) == ["done", "done", "done", "failed", "failed"]
    # The damaged and the missing run: the command's message and exit status; the
    # others went on.
    for i in (-2, -1):
        code, line = cli.error("reduce", runs[i], "--out", tmp_path / "x.csv")
        bad = df.iloc[i]
        assert bad["error"] == line and bad["exit_code"] == code == 2
        assert pd.isna(bad["samples"]) and pd.isna(bad["dir"])
    for _, row in df.iloc[:-2].iterrows():
        d = pathlib.Path(row["dir"])
        ref = tmp_path / f"ref-{d.name}"
        ref.mkdir()
        cli.run("reduce", row["run"], "--out", ref / "reduced.csv")
        cli.run("fit", row["run"], "--lobes", "2", "--out", ref / "model.toml")
        for name in ("reduced.csv", "reduced.csv.json", "model.toml"):
            assert (d / name).read_bytes() == (ref / name).read_bytes(), name
        check = cli_json(cli, "check", row["run"])
        assert json.loads((d / "check.json").read_text()) == check
        fit = cli_json(cli, "fit", row["run"], "--lobes", "2", "--out", ref / "m2.toml")
        assert json.loads((d / "fit.json").read_text()) == fit
        assert row["P_r"] == max(check["reciprocity"])
        chi2 = {c["channel"]: c["reduced_chi2"] for c in fit["fit"]["channels"]}
        assert row["chi2"] == chi2 and row["samples"] == fit["fit"]["samples"]
    # Inputs are only read: same bytes, and nothing made beside them.
    assert digests(archive) == before
    # Nothing half-made is left in the output directory.
    assert sorted(p.name for p in out.iterdir()) == sorted(df["key"][:-2])


def test_a_rerun_skips_what_is_done_and_force_writes_the_same_bytes(
    archive: pathlib.Path, client2: Any, cli: Cli, tmp_path: pathlib.Path
) -> None:
    runs = [archive / "p5.gonio", archive / "p7.gonio"]
    out = tmp_path / "out"
    steps = ("reduce", "fit", "report")
    first = batch.reprocess(runs, out, client2, steps=steps)
    assert list(first["status"]) == ["done", "done"], first["error"].tolist()
    for _, row in first.iterrows():
        ref = tmp_path / f"ref-{row['key']}"
        cli.run("report", row["run"], "--out", ref)
        assert (pathlib.Path(row["dir"]) / "report.html").read_bytes() == (
            ref / "report.html"
        ).read_bytes()
    files = digests(out)
    stamps = {p: p.stat().st_mtime_ns for p in out.rglob("*") if p.is_file()}
    again = batch.reprocess(runs, out, client2, steps=steps)
    assert list(again["status"]) == ["skipped", "skipped"]
    keep = ["run", "key", "dir", "samples", "chi2", "fit", "files"]
    assert again[keep].equals(first[keep])
    assert {p: p.stat().st_mtime_ns for p in stamps} == stamps, "nothing rewritten"
    forced = batch.reprocess(runs, out, client2, steps=steps, force=True)
    assert list(forced["status"]) == ["done", "done"]
    assert digests(out) == files
    # Other options are other outputs, beside the first.
    other = batch.reprocess(runs[:1], out, client2, steps=("fit",), lobes=1)
    assert other["key"][0] not in set(first["key"])


def test_bad_options_are_refused_before_anything_is_made(
    archive: pathlib.Path, client2: Any, cli: Cli, tmp_path: pathlib.Path
) -> None:
    out = tmp_path / "never"
    with pytest.raises(TypeError, match="lobez"):
        batch.reprocess([archive / "p5.gonio"], out, client2, lobez=2)
    p = cli.run(
        "fit", archive / "p5.gonio", "--lobes", "many", "--out", tmp_path / "m", check=False
    )
    with pytest.raises(gonio.InputError) as e:
        batch.reprocess([archive / "p5.gonio"], out, client2, lobes="many")
    # clap's first line, as the package's every parse error.
    assert str(e.value) == p.stderr.splitlines()[0].removeprefix("error: ")
    assert e.value.exit_code == p.returncode == 2
    # A value the command checks before reading its input: refused up front too.
    p = cli.run("check", archive / "p5.gonio", "--calibration", "none", check=False)
    with pytest.raises(gonio.InputError) as e:
        batch.reprocess([archive / "p5.gonio"], out, client2, calibration="none")
    assert f"gonio: {e.value}" == p.stderr.strip().splitlines()[-1] and p.returncode == 2
    with pytest.raises(gonio.InputError, match="unexpected argument '1'"):
        batch.micro_sweep(SAWTOOTH, {"isotropic": 1}, client2, out_dir=out)
    with pytest.raises(ValueError, match="no run files"):
        batch.reprocess(tmp_path / "*.gonio", out, client2)
    with pytest.raises(ValueError, match="steps"):
        batch.reprocess([archive / "p5.gonio"], out, client2, steps=("plot",))
    with pytest.raises(gonio.ConfigError) as e:
        batch.micro_sweep(tmp_path / "missing.toml", {"rays": 10}, client2)
    assert e.value.exit_code == 2 and "missing.toml" in str(e.value)
    with pytest.raises(ValueError, match="sh_out"):
        batch.micro_sweep(SAWTOOTH, {"sh_out": "x"}, client2)
    with pytest.raises(gonio.ConfigError, match="params\\[0\\]"):
        batch.micro_sweep(SAWTOOTH, {"period": -1.0}, client2, out_dir=out)
    assert not out.exists()


#: Two parameter sets of the sawtooth: three segments of rays in chunks of one
#: (its own seed), and a surface edit with a derived seed.
PARAMS = [
    {"rays": 2 * SEG + 1000, "grid": (30, 90), "isotropic": True, "seed": 5},
    {"rays": 20_000, "grid": (30, 45), "theta_i": [20, 50], "angles_deg": [30.0, 30.0]},
]


def sweep(n_workers: int, out: pathlib.Path) -> Any:
    with cluster(n_workers) as c, distributed.Client(c) as cl:
        return batch.micro_sweep(SAWTOOTH, PARAMS, cl, seed=9, out_dir=out, chunk_rays=SEG)


@pytest.fixture(scope="module")
def swept(tmp_path_factory: pytest.TempPathFactory) -> dict[int, tuple[Any, pathlib.Path]]:
    d = tmp_path_factory.mktemp("sweeps")
    return {n: (sweep(n, d / f"w{n}"), d / f"w{n}") for n in (1, 2)}


def test_a_sweep_is_the_same_bytes_on_one_and_two_workers_and_as_gonio_micro(
    swept: dict[int, tuple[Any, pathlib.Path]], cli: Cli, tmp_path: pathlib.Path
) -> None:
    (df1, out1), (df2, out2) = swept[1], swept[2]
    assert digests(out1) == digests(out2)
    assert df1.equals(df2)
    tables = df1.attrs["tables"]
    assert [t["set"] for t in tables] == [0, 1] and tables[0]["seed"] == 5
    # The first table is gonio micro's with the same seed, byte for byte, though
    # it was traced in nine chunks on two machines' worth of processes.
    ref = tmp_path / "ref.csv"
    cli.run(
        "micro",
        SAWTOOTH,
        "--rays",
        PARAMS[0]["rays"],
        "--grid",
        "30,90",
        "--isotropic",
        "--seed",
        "5",
        "--out",
        ref,
    )
    name = tables[0]["name"]
    assert (out1 / f"{name}.csv").read_bytes() == ref.read_bytes()
    assert (out1 / f"{name}.csv.json").read_bytes() == (tmp_path / "ref.csv.json").read_bytes()
    # The second: the edited surface, as a file, with the derived seed.
    text = SAWTOOTH.read_text().replace("angles_deg = [45.0, 45.0]", "angles_deg = [30.0, 30.0]")
    assert text != SAWTOOTH.read_text()
    edited = tmp_path / "edited.toml"
    edited.write_text(text)
    seed = tables[1]["seed"]
    assert seed != 9 and 0 <= seed < 2**63
    ref2 = tmp_path / "ref2.csv"
    cli.run("micro", edited, "--rays", "20000", "--grid", "30,45", "--seed", seed, "--out", ref2)
    got = gonio.read_csv(out1 / f"{tables[1]['name']}.csv")
    want = gonio.read_csv(ref2)
    # theta_i [20, 50] replaces the grid's incident angles (15, 45, 75): the nodes
    # differ, the random streams of the same node index do not.
    assert sorted(set(got["theta_i_deg"])) == [20.0, 50.0]
    assert len(got) == len(want[want["theta_i_deg"] < 60])
    # Rows of the returned frame are the tables, one below the other.
    assert len(df1) == sum(len(gonio.read_csv(out1 / f"{t['name']}.csv")) for t in tables)


def test_run_names_with_glob_characters_are_taken_as_they_are(
    archive: pathlib.Path, tmp_path: pathlib.Path
) -> None:
    d = tmp_path / "arch[2024]"
    d.mkdir()
    shutil.copy(archive / "p5.gonio", d / "run[1].gonio")
    (d / "run1.gonio").write_bytes(b"not this one")
    assert batch.find_runs(d) == sorted([str(d / "run[1].gonio"), str(d / "run1.gonio")])
    assert batch.find_runs([d / "run[1].gonio"]) == [str(d / "run[1].gonio")]


def test_a_sweep_done_before_is_read_back(
    swept: dict[int, tuple[Any, pathlib.Path]], client2: Any
) -> None:
    df1, out1 = swept[1]
    stamps = {p: p.stat().st_mtime_ns for p in out1.iterdir()}
    again = batch.micro_sweep(SAWTOOTH, PARAMS, client2, seed=9, out_dir=out1, chunk_rays=SEG)
    assert again.equals(df1)
    assert again.attrs["tables"] == df1.attrs["tables"]
    # Asked for in another order: read back under this call's set numbers.
    swapped = batch.micro_sweep(SAWTOOTH, PARAMS[::-1], client2, seed=9, out_dir=out1)
    assert [t["set"] for t in swapped.attrs["tables"]] == [0, 1]
    assert [t["name"] for t in swapped.attrs["tables"]] == [
        t["name"] for t in df1.attrs["tables"][::-1]
    ]
    assert {p: p.stat().st_mtime_ns for p in out1.iterdir()} == stamps


def test_a_damaged_kept_chunk_is_traced_again(
    swept: dict[int, tuple[Any, pathlib.Path]], client2: Any, tmp_path: pathlib.Path
) -> None:
    _, reference = swept[1]
    out = tmp_path / "resumed"
    tables = batch._sweep.plan([SAWTOOTH], PARAMS, 9)
    kept = out / ".tmp-parts" / tables[0].name
    kept.mkdir(parents=True)
    (kept / "0-0-1.part").write_bytes(b"GMTPART2 damaged")
    batch.micro_sweep(SAWTOOTH, PARAMS, client2, seed=9, out_dir=out, chunk_rays=SEG)
    assert digests(out) == digests(reference)


def kill_a_busy_worker(work: Any) -> tuple[Any, int]:
    """Runs ``work(client)`` on a fresh 2-worker cluster in a thread and, as soon
    as a worker process is running a task, kills it (SIGKILL). Returns what
    ``work`` returned and the killed process's id, once the nanny has replaced it."""
    with cluster(2) as c, distributed.Client(c) as cl:
        pids = cl.run(os.getpid)
        result: dict[str, Any] = {}

        def go() -> None:
            try:
                result["value"] = work(cl)
            except BaseException as e:  # reported by the assertion below
                result["error"] = e

        t = threading.Thread(target=go)
        t.start()
        victim = None
        deadline = time.monotonic() + 60
        while victim is None and t.is_alive() and time.monotonic() < deadline:
            busy = [addr for addr, keys in cl.processing().items() if keys and addr in pids]
            if busy:
                victim = pids[busy[0]]
                os.kill(victim, signal.SIGKILL)
            else:
                time.sleep(0.001)
        t.join(180)
        assert victim is not None, "a worker was running a task"
        assert not t.is_alive(), "the work finished"
        assert "error" not in result, result.get("error")
        assert victim not in cl.run(os.getpid).values(), "the killed worker was replaced"
        return result["value"], victim


def test_a_worker_killed_mid_sweep_changes_no_byte(
    swept: dict[int, tuple[Any, pathlib.Path]], tmp_path: pathlib.Path
) -> None:
    df1, reference = swept[1]
    out = tmp_path / "killed"
    df, _ = kill_a_busy_worker(
        lambda cl: batch.micro_sweep(SAWTOOTH, PARAMS, cl, seed=9, out_dir=out, chunk_rays=SEG)
    )
    assert digests(out) == digests(reference)
    assert df.equals(df1)


def test_a_worker_killed_mid_reprocess_changes_no_byte(
    archive: pathlib.Path, client2: Any, tmp_path: pathlib.Path
) -> None:
    runs = sorted(archive.glob("h*.gonio"))
    first = batch.reprocess(runs, tmp_path / "first", client2)
    assert set(first["status"]) == {"done"}
    out = tmp_path / "killed"
    df, _ = kill_a_busy_worker(lambda cl: batch.reprocess(runs, out, cl))
    assert set(df["status"]) == {"done"}, df["error"].tolist()
    assert digests(out) == digests(tmp_path / "first")


def batch_cli(*args: Any) -> subprocess.CompletedProcess[str]:
    """``python -m gonio.batch ARGS`` in this interpreter."""
    argv = [sys.executable, "-m", "gonio.batch", *map(str, args)]
    return subprocess.run(argv, capture_output=True, text=True, cwd=ROOT, timeout=300)


def test_the_command_line(archive: pathlib.Path, tmp_path: pathlib.Path) -> None:
    sweep_file = tmp_path / "sweep.toml"
    sweep_file.write_text(
        f'surfaces = ["{SAWTOOTH}"]\nseed = 9\n\n[[params]]\nrays = 5000\ngrid = [30, 90]\n'
        "isotropic = true\n"
    )
    out = tmp_path / "micro"
    p = batch_cli("micro", sweep_file, "--out", out, "--workers", "1")
    assert p.returncode == 0, p.stderr
    assert "dashboard http://127.0.0.1:" in p.stderr
    index = gonio.read_csv(out / "sweep.csv")
    assert list(index["theta_i"]) == pytest.approx([15.0, 45.0, 75.0], abs=1e-12)
    assert {"albedo_R", "albedo_sigma_B"} <= set(index.columns)
    # A reprocess with a damaged run: the others done, exit status 1.
    runs = [archive / "p5.gonio", archive / "bad" / "damaged.gonio"]
    out = tmp_path / "re"
    p = batch_cli(
        "reprocess",
        *runs,
        "--out",
        out,
        "--workers",
        "1",
        "--steps",
        "reduce,fit",
        "--set",
        "lobes=1",
    )
    assert p.returncode == 1, p.stderr
    assert "1 done, 0 done before, 1 failed" in p.stdout
    rows = gonio.read_csv(out / "reprocess.csv")
    assert list(rows["status"]) == ["done", "failed"]
    # Bad input: exit status 2, nothing started.
    p = batch_cli("reprocess", runs[0], "--out", tmp_path / "no", "--set", "lobez=1")
    assert p.returncode == 2 and "lobez" in p.stderr
    wrong = tmp_path / "wrong.toml"
    wrong.write_text(f'surfaces = ["{SAWTOOTH}"]\n[[params]]\nrays = 1\n')
    p = batch_cli("micro", wrong, "--out", tmp_path / "no")
    assert p.returncode == 2, p.stderr
    assert f"{wrong}: " in p.stderr and "params[0]" in p.stderr and "rays" in p.stderr
    bad = tmp_path / "bad.toml"
    bad.write_text('surfaces = ["x.toml"]\nsead = 1\n[[params]]\nrays = 10\n')
    p = batch_cli("micro", bad, "--out", tmp_path / "no")
    assert p.returncode == 2 and "bad.toml" in p.stderr and "sead" in p.stderr
    assert not (tmp_path / "no").exists()
    shutil.rmtree(tmp_path / "micro")
