"""lancet: GPU-accelerated soft-tissue simulation with cutting, for surgical simulators.

- ``run_scene(path=None, overrides=None, ...)`` runs a scene file (or the embedded default
  scene) with its expectations and returns the summary as a dict.
- ``World`` holds the tissue, its tools, cutting and contact: pose the tools, ``step()``, read
  the forces and ``positions`` (a NumPy array). ``World.preset(...)`` is the mass-spring box
  of ``lancet bench --preset`` that ``benches/peers/`` runs in Taichi and Warp.
- ``read_mesh(path)`` reads a tetrahedral mesh (``nodes`` and ``tets`` as NumPy arrays).
- ``bench(cubes=..., engines=..., layouts=...)`` times the engines and GPU layouts (the rows of
  ``lancet bench --json``); ``accuracy(path, ladder=...)`` measures error against run time on a
  scene (``lancet report accuracy --json``).
- ``lancet.sweep`` runs scenes, benchmarks and accuracy ladders over parameter grids, serially
  or on a Dask cluster.

Errors of the library are raised as ``LancetError`` with the library's message.
"""

from ._lancet import (
    LancetError,
    Mesh,
    World,
    __version__,
    accuracy,
    bench,
    read_mesh,
    run_scene,
)

__all__ = [
    "LancetError",
    "Mesh",
    "World",
    "__version__",
    "accuracy",
    "bench",
    "read_mesh",
    "run_scene",
    "sweep",
]

from . import sweep  # noqa: E402  (after the extension, which it uses)
