"""Sweeps: scenes times parameters, run serially, on threads or processes, or on a Dask
cluster, with results gathered as JSON-able dicts.

A job is one scene run: a scene (a path, or None for the embedded default scene), the scene
fields to override (dotted paths, as ``run_scene`` takes them) and the run options
(``engine``, ``steps``, ``cut_method``). ``grid`` makes the jobs of every combination;
``run`` runs them and returns one result per job, in the jobs' order, whatever ran them::

    from lancet import sweep
    jobs = sweep.grid(scenes=[None], engine=["reference", "fast"], steps=[100, 200],
                      overrides={"material.density": [900.0, 1100.0]})
    results = sweep.run(jobs)                      # serially, here
    results = sweep.run(jobs, client=dask_client)  # on a Dask cluster
    sweep.write_json(results, "sweep.json")

Each result is the job and the run's summary (``expectations_passed``, ``max_displacement``,
``energy``, ``steps_per_s``, ...), or the job and the error message where the run failed, so a
sweep never stops at one bad combination.

A job's ``kind`` says what it runs: ``"run"`` (the default: the scene, as above),
``"accuracy"`` (error against run time on the scene, ``lancet.accuracy``; options ``engines``,
``layouts``, ``ladder``, ``implicit_ladder``) or ``"bench"`` (the engines and layouts timed on
cubes or the peers' preset, ``lancet.bench``; options ``cubes``, ``engines``, ``layouts``,
``steps``, ``integrator``, ``preset``; no scene). Their results carry ``report`` instead of
``summary``::

    jobs = sweep.grid(kind="accuracy", scenes=[None], ladder=[[1.0, 0.5], [0.25]],
                      overrides={"steps": [200]})
    jobs += sweep.grid(kind="bench", cubes=[[6], [10]], layouts=[["connectivity", "edges"]])
"""

from __future__ import annotations

import itertools
import json
import os
from typing import Any, Iterable, Mapping, Optional, Sequence

#: Run options a job may carry besides its overrides (the options of ``run_scene``).
RUN_OPTIONS = ("engine", "steps", "cut_method")

#: The options of each kind of job (the keyword arguments of the function that runs it).
OPTIONS = {
    "run": RUN_OPTIONS,
    "accuracy": ("engines", "layouts", "ladder", "implicit_ladder"),
    "bench": ("cubes", "engines", "layouts", "steps", "integrator", "preset"),
}


def grid(
    scenes: Sequence[Optional[str]] = (None,),
    overrides: Optional[Mapping[str, Sequence[Any]]] = None,
    kind: str = "run",
    **options: Sequence[Any],
) -> list[dict]:
    """The jobs of every combination of ``scenes``, each override's values and each option's
    values (``engine=[...]``, ``steps=[...]``, ``cut_method=[...]`` for runs; see ``OPTIONS``
    for the other kinds). A benchmark takes no scene and no overrides."""
    if kind not in OPTIONS:
        raise ValueError(f"unknown kind {kind!r}: use one of {sorted(OPTIONS)}")
    allowed = OPTIONS[kind]
    unknown = set(options) - set(allowed)
    if unknown:
        raise ValueError(f"unknown {kind} options {sorted(unknown)}: use {allowed}")
    if kind == "bench" and (overrides or list(scenes) != [None]):
        raise ValueError("a benchmark runs generated meshes: give it no scenes or overrides")
    overrides = dict(overrides or {})
    keys = list(overrides)
    option_keys = list(options)
    jobs = []
    for scene in scenes:
        for values in itertools.product(*(overrides[k] for k in keys)):
            for option_values in itertools.product(*(options[k] for k in option_keys)):
                jobs.append(
                    {
                        "kind": kind,
                        "scene": None if scene is None else os.fspath(scene),
                        "overrides": dict(zip(keys, values)),
                        **dict(zip(option_keys, option_values)),
                    }
                )
    return jobs


def run_job(job: Mapping[str, Any]) -> dict:
    """Run one job in this process and return ``{"job": job, "summary": ...}`` (a run) or
    ``{"job": job, "report": ...}`` (accuracy, bench), or ``{"job": job, "error": message}``
    when it could not be made."""
    from . import _lancet

    kind = job.get("kind", "run")
    if kind not in OPTIONS:
        return {"job": dict(job), "error": f"unknown kind {kind!r}: use one of {sorted(OPTIONS)}"}
    kwargs = {k: job[k] for k in OPTIONS[kind] if job.get(k) is not None}
    overrides = job.get("overrides") or None
    try:
        if kind == "run":
            return {
                "job": dict(job),
                "summary": _lancet.run_scene(job.get("scene"), overrides=overrides, **kwargs),
            }
        if kind == "accuracy":
            report = _lancet.accuracy(job.get("scene"), overrides=overrides, **kwargs)
        else:
            report = _lancet.bench(**kwargs)
    except (_lancet.LancetError, ValueError) as e:
        return {"job": dict(job), "error": str(e)}
    return {"job": dict(job), "report": report}


def run(jobs: Iterable[Mapping[str, Any]], client=None, executor=None) -> list[dict]:
    """Run ``jobs`` and return their results in order: on a Dask ``client`` (its workers
    must import ``lancet``), on a ``concurrent.futures`` ``executor``, or serially."""
    jobs = [dict(j) for j in jobs]
    if client is not None:
        futures = client.map(run_job, jobs, pure=False)
        return client.gather(futures)
    if executor is not None:
        return list(executor.map(run_job, jobs))
    return [run_job(j) for j in jobs]


def write_json(results: Sequence[Mapping[str, Any]], path) -> None:
    """Write ``results`` as one JSON document (a list), atomically: to a temporary file in
    the same folder, then renamed over ``path``."""
    path = os.fspath(path)
    tmp = f"{path}.tmp{os.getpid()}"
    with open(tmp, "w") as f:
        json.dump(list(results), f, indent=1)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)
