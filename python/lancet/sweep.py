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
"""

from __future__ import annotations

import itertools
import json
import os
from typing import Any, Iterable, Mapping, Optional, Sequence

#: Run options a job may carry besides its overrides (the options of ``run_scene``).
RUN_OPTIONS = ("engine", "steps", "cut_method")


def grid(
    scenes: Sequence[Optional[str]] = (None,),
    overrides: Optional[Mapping[str, Sequence[Any]]] = None,
    **options: Sequence[Any],
) -> list[dict]:
    """The jobs of every combination of ``scenes``, each override's values and each run
    option's values (``engine=[...]``, ``steps=[...]``, ``cut_method=[...]``)."""
    unknown = set(options) - set(RUN_OPTIONS)
    if unknown:
        raise ValueError(f"unknown run options {sorted(unknown)}: use {RUN_OPTIONS}")
    overrides = dict(overrides or {})
    keys = list(overrides)
    option_keys = list(options)
    jobs = []
    for scene in scenes:
        for values in itertools.product(*(overrides[k] for k in keys)):
            for option_values in itertools.product(*(options[k] for k in option_keys)):
                jobs.append(
                    {
                        "scene": None if scene is None else os.fspath(scene),
                        "overrides": dict(zip(keys, values)),
                        **dict(zip(option_keys, option_values)),
                    }
                )
    return jobs


def run_job(job: Mapping[str, Any]) -> dict:
    """Run one job in this process and return ``{"job": job, "summary": ...}``, or
    ``{"job": job, "error": message}`` when the run could not be made."""
    from . import _lancet

    kwargs = {k: job[k] for k in RUN_OPTIONS if job.get(k) is not None}
    try:
        summary = _lancet.run_scene(job.get("scene"), overrides=job.get("overrides") or None, **kwargs)
    except (_lancet.LancetError, ValueError) as e:
        return {"job": dict(job), "error": str(e)}
    return {"job": dict(job), "summary": summary}


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
