"""Sweeps: the grid makes every combination; a sweep on a local Dask cluster returns the same
results as the same jobs run serially; a failing job is reported, not raised."""

import json

import pytest

import lancet
from lancet import sweep


def test_grid_makes_every_combination():
    jobs = sweep.grid(scenes=[None, "a.ron"], engine=["reference", "fast"], overrides={"steps": [5, 6, 7]})
    assert len(jobs) == 2 * 2 * 3
    assert {(j["scene"], j["engine"], j["overrides"]["steps"]) for j in jobs} == {
        (s, e, n) for s in (None, "a.ron") for e in ("reference", "fast") for n in (5, 6, 7)
    }
    with pytest.raises(ValueError, match="unknown run options"):
        sweep.grid(layout=["edges"])


def test_a_failing_job_is_reported_with_its_message():
    (result,) = sweep.run([{"scene": "/nonexistent/x.ron"}])
    assert "x.ron" in result["error"]


def test_a_dask_cluster_gives_the_serial_results(tmp_path):
    distributed = pytest.importorskip("distributed")
    jobs = sweep.grid(engine=["reference", "fast"], overrides={"steps": [40, 80]})
    serial = sweep.run(jobs)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        with distributed.Client(cluster) as client:
            remote = sweep.run(jobs, client=client)
    assert len(remote) == len(jobs)
    for s, r in zip(serial, remote):
        assert s["job"] == r["job"]
        # Deterministic engines: the same numbers, wherever they ran (wall time aside).
        for key in ("steps", "max_displacement", "volume_ratio", "energy", "expectations_passed"):
            assert s["summary"][key] == r["summary"][key], key
    out = tmp_path / "sweep.json"
    sweep.write_json(remote, out)
    assert len(json.loads(out.read_text())) == len(jobs)
