"""Benchmarks and accuracy ladders from Python: the rows `lancet bench` and `lancet report
accuracy` give, checked against physics (float32 against float64, the error falling with the
step), and as jobs of a sweep."""

import pytest

import lancet
from lancet import sweep


def test_bench_times_each_engine_and_the_fast_one_stays_on_float64():
    report = lancet.bench(cubes=[3], engines=["reference", "fast"], steps=20)
    rows = {r["engine"]: r for r in report["rows"]}
    assert set(rows) == {"cpu-reference-f64", "cpu-fast-f32"}, list(rows)
    for r in rows.values():
        assert r["nodes"] == 4 ** 3 and r["ms_per_step"] > 0.0
        assert r["bytes_per_step"] > 0 and r["floor_ratio"] > 0.0
    # The float64 engine is the reference. Float32 differs by its rounding only: relative to
    # the small displacement of a few dozen steps (positions of 1 cm rounded at 6e-8 against
    # micrometres of motion) that is 1e-5 to 1e-4; a wrong force would be off by order one.
    assert rows["cpu-reference-f64"]["error_vs_reference"] == 0.0
    assert 0.0 < rows["cpu-fast-f32"]["error_vs_reference"] < 1e-3
    assert report["bandwidth"]["bytes_per_s"] > 0.0


def test_bench_refuses_what_it_cannot_run_with_a_value_error():
    with pytest.raises(ValueError, match="layout `diagonal`"):
        lancet.bench(layouts=["diagonal"])
    with pytest.raises(ValueError, match="preset"):
        lancet.bench(preset="heavy")


def test_accuracy_error_falls_as_the_step_shrinks():
    # The default beam, shortened; Verlet from rest under gravity converges at first order.
    report = lancet.accuracy(None, engines=["reference"], ladder=[1.0, 0.25], implicit_ladder=[],
                             overrides={"steps": 200})
    rows = {r["fraction"]: r for r in report["rows"] if r["series"] == "cpu-reference-f64"}
    assert set(rows) == {1.0, 0.25}
    coarse = max(e["relative_l2"] for e in rows[1.0]["errors"])
    fine = max(e["relative_l2"] for e in rows[0.25]["errors"])
    assert 0.0 < fine < coarse / 2.0, (fine, coarse)
    with pytest.raises(ValueError, match="ladder"):
        lancet.accuracy(None, ladder=[1.5])


def test_a_sweep_runs_accuracy_and_bench_jobs_beside_scene_runs():
    jobs = sweep.grid(kind="accuracy", engines=[["reference"]], ladder=[[1.0]], implicit_ladder=[[]],
                      overrides={"steps": [100]})
    jobs += sweep.grid(kind="bench", cubes=[[2], [3]], engines=[["reference", "fast"]], steps=[10])
    jobs += sweep.grid(steps=[10])
    results = sweep.run(jobs)
    assert [r["job"]["kind"] for r in results] == ["accuracy", "bench", "bench", "run"]
    assert all("error" not in r for r in results), results
    assert results[0]["report"]["rows"][0]["fraction"] == 1.0
    assert [r["report"]["rows"][0]["nodes"] for r in results[1:3]] == [3 ** 3, 4 ** 3]
    assert results[3]["summary"]["steps"] == 10
    with pytest.raises(ValueError, match="no scenes"):
        sweep.grid(kind="bench", scenes=["a.ron"])
    with pytest.raises(ValueError, match="unknown bench options"):
        sweep.grid(kind="bench", ladder=[[1.0]])
