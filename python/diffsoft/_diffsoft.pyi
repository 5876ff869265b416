"""Type stubs of diffsoft's native module."""

from __future__ import annotations

from os import PathLike
from typing import Any, final

import numpy as np
import numpy.typing as npt
from typing_extensions import TypeAlias

__all__ = [
    "Run",
    "Scene",
    "__version__",
    "_run_from_state",
    "_scene_from_state",
    "_trajectory_steps",
    "array_parameters",
    "bounds",
    "grad_batch",
    "gradcheck",
    "jacobians",
    "mesh_box",
    "scalar_parameters",
    "simulate_batch",
    "vjp_batch",
]

__version__: str

# Private: the stubs' own shorthands, not names of the module.
_FloatArray: TypeAlias = npt.NDArray[np.float64]
_ParamValue: TypeAlias = float | npt.ArrayLike

@final
class Run:
    """The result of ``Scene.simulate``."""

    positions: _FloatArray
    """Positions of every state, ``(steps + 1, n, 3)``; state 0 is the initial state."""
    velocities: _FloatArray
    """Velocities of every state, ``(steps + 1, n, 3)``."""
    times: _FloatArray
    """Time of every state, ``(steps + 1,)``."""
    stats: dict[str, Any]
    """The run log (as ``run.json``): ``summary``, ``certificate``, ``settings``,
    ``unconverged_steps`` and ``steps`` (one dict per step: iterations, converged, contacts,
    energies, timings)."""
    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        """Pickling and copying by value (its arrays and log)."""

@final
class Scene:
    """A scene ready to simulate and differentiate."""

    @staticmethod
    def load(path: str | PathLike[str], passive: bool = False) -> Scene:
        """Read a scene: native ``diffsoft.scene/1`` or the paper's format.

        Raises ``FileError`` (an ``OSError``) if the file cannot be read, ``InputError`` (a
        ``ValueError``, naming file, line and column) if it is malformed, and ``TypeError`` for a
        ``path`` that is neither a str nor an ``os.PathLike`` giving one. Each file is read once;
        the scene and its pickle are built from the same bytes."""
    def set(self, name: str, value: _ParamValue) -> None:
        """Set a scalar (``youngs_modulus``, ``gravity.y``, ...) or array parameter
        (``initial_positions``, ``youngs_modulus_per_tet``, ``activations``, ...): a name of
        ``scalar_parameters()`` or ``array_parameters()``. Raises SceneBusyError while a
        batch or gradcheck on another thread reads the scene."""
    def get(self, name: str) -> float | _FloatArray | None:
        """A parameter's value (``None``: per-step controls that follow the schedules)."""
    def configure(self, **settings: Any) -> None:
        """Change solver settings by their scene-file names (``solver``, ``tolerance``,
        ``max_iterations``, ``dt``, ``anderson``, ...), each checked as it is set; a call that
        fails (``ValueError`` naming the setting, or ``SceneBusyError`` while a batch or
        ``gradcheck`` on another thread reads the scene) changes nothing."""
    @property
    def settings(self) -> dict[str, Any]:
        """The solver settings."""
    @property
    def n_vertices(self) -> int: ...
    @property
    def n_tets(self) -> int: ...
    @property
    def n_attachments(self) -> int: ...
    @property
    def dt(self) -> float: ...
    @property
    def path(self) -> str: ...
    @property
    def notes(self) -> list[str]:
        """The importer's notes, then each body's material notes (projective response, a body
        too soft to carry its own weight) from the scene's current parameters."""
        ...
    @property
    def materials(self) -> list[dict[str, Any]]:
        """Every body's material: name, model, youngs_modulus, poisson_ratio and, for the
        projective model, effective_youngs_modulus and effective_poisson_ratio."""
        ...
    @property
    def actuator_groups(self) -> list[str]:
        """Names of the actuator groups, the columns of ``activations``."""
    @property
    def joint_dofs(self) -> int:
        """Reduced joint coordinates, the columns of ``torques``."""
    @property
    def masses(self) -> _FloatArray:
        """Lumped vertex masses (kg), ``(n,)``."""
    @property
    def fixed(self) -> list[bool]:
        """Whether each vertex is pinned."""
    def copy(self) -> Scene: ...
    def simulate(self, steps: int) -> Run:
        """Simulate ``steps`` steps (raises ``DivergenceError``, a ``RuntimeError``, on
        divergence or a non-finite state). Steps that stop at ``max_iterations`` before meeting
        a positive tolerance raise a ``ConvergenceWarning`` at the caller's line."""
    def grad(
        self,
        steps: int,
        loss: str = "final_com.y",
        params: list[str] | None = None,
        mode: str = "unrolled",
        allow_unconverged: bool = False,
        stats: dict[str, Any] | None = None,
    ) -> tuple[float, dict[str, float | _FloatArray]]:
        """The loss (``final_com.x|y|z``, ``mean_com.x|y|z``, ``joint_angle.BONE``,
        ``mean_joint_angle.BONE``) and its derivatives with respect to ``params``. A forward
        that misses its tolerance (or an unrolled replay that deviates from it) raises
        ``ConvergenceError`` (a ``RuntimeError``) unless ``allow_unconverged``. A dict given as
        ``stats`` is filled with the gradient's statistics (``diffsoft grad --json``'s
        ``stats``: times, iterations, ``forward_gap``, ``unrolled_leftover``, ...)."""
    def vjp(
        self,
        steps: int,
        params: list[str],
        cotangent: npt.ArrayLike,
        velocity_cotangent: npt.ArrayLike | None = None,
        mode: str = "unrolled",
        allow_unconverged: bool = False,
        stats: dict[str, Any] | None = None,
    ) -> dict[str, float | _FloatArray]:
        """Gradient of ``sum(cotangent * positions) + sum(velocity_cotangent * velocities)``
        (both ``(steps + 1, n, 3)``) with respect to ``params``; ``allow_unconverged`` and
        ``stats`` as in ``grad``."""

    # Scenes as data, pickling and accessors.
    @staticmethod
    def from_dict(d: dict[str, Any], base_dir: str | PathLike[str] | None = None) -> Scene:
        """A scene from a dict of the scene file's structure (``schemas/scene.schema.json``;
        ``schema`` may be left out). A mesh is a file path (relative to ``base_dir``, by default
        the working directory) or arrays: ``{"vertices": (n, 3), "tets": (m, 4)}`` for a body,
        ``{"vertices": (n, 3), "triangles": (k, 3)}`` for a cloth or an obstacle's ``file``."""
    @staticmethod
    def from_meshio(mesh: Any, scene: dict[str, Any] | None = None, **body: Any) -> Scene:
        """A scene of one body from a ``meshio.Mesh`` (its ``tetra`` cells): ``body`` holds the
        body's keys (``material``, ``density`` or ``total_mass``, ``name``, ...), ``scene`` the
        scene's other keys (``time_step`` or ``solver.dt``, ``gravity``, ``obstacles``, ...)."""
    def to_dict(self) -> dict[str, Any]:
        """The scene as a dict of the scene file's structure, meshes inline as lists (``json.dump``
        writes a scene file) and ``solver`` the current settings; ``set`` values are not part
        of it (pickling keeps them). Raises ``UnsupportedError`` for paper-format scenes."""
    @property
    def tets(self) -> npt.NDArray[np.int64]:
        """Every tet, ``(m, 4)``, in the global vertex numbering."""
    @property
    def surface_triangles(self) -> npt.NDArray[np.int64]:
        """Boundary faces of the tets, ``(k, 3)``, oriented outward."""
    @property
    def bodies(self) -> list[dict[str, Any]]:
        """Every body: ``name``, ``kind`` (``soft``, ``cloth``), ``vertices`` ``(start, stop)``
        and ``tets`` (soft) or ``triangles`` (cloth) ``(start, stop)``."""
    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        """Pickling by value: document (meshes inline), settings and the parameters set."""
    def __copy__(self) -> Scene: ...
    def __deepcopy__(self, memo: Any) -> Scene: ...

def grad_batch(
    scene: Scene,
    steps: int,
    loss: str,
    params: list[str],
    values: list[dict[str, _ParamValue]],
    mode: str = "unrolled",
    allow_unconverged: bool = False,
) -> list[tuple[float, dict[str, float | _FloatArray]]]:
    """``scene.grad`` for every parameter set of ``values``, in parallel on all cores (one set
    per core, each single-threaded when the sets are at least as many as the cores)."""

def simulate_batch(scene: Scene, steps: int, values: list[dict[str, _ParamValue]]) -> list[Run]:
    """``scene.simulate`` for every parameter set of ``values``, in parallel on all cores (one
    set per core, each single-threaded when the sets are at least as many as the cores); one
    ``ConvergenceWarning`` if any run missed a positive tolerance."""

def vjp_batch(
    scene: Scene,
    steps: int,
    params: list[str],
    values: list[dict[str, _ParamValue]],
    cotangents: list[npt.ArrayLike],
    velocity_cotangents: list[npt.ArrayLike | None] | None = None,
    mode: str = "unrolled",
    allow_unconverged: bool = False,
) -> list[dict[str, float | _FloatArray]]:
    """``scene.vjp`` for every item, in parallel like ``grad_batch``: ``values[k]`` sets
    parameters on a copy of ``scene`` and ``cotangents[k]`` (``(steps + 1, n, 3)``, with
    ``velocity_cotangents[k]`` if given) pairs with its trajectory."""

def bounds(
    mesh: str | PathLike[str],
    rho: float,
    mu: float,
    dt: float,
    scale: float = 1.0,
    empirical: bool = False,
    method: str = "auto",
) -> dict[str, Any]:
    """The ``diffsoft bounds`` report: spectral radii and critical time steps of the paper's
    iterations (19) and (21) on a mesh, with the appendix's verdicts."""

def gradcheck(
    scene: Scene,
    steps: int,
    loss: str = "final_com.y",
    params: list[str] | None = None,
    iterations: int | None = None,
    seed: int = 2021,
) -> dict[str, Any]:
    """A ``diffsoft gradcheck`` case on ``scene``: reverse mode against central differences
    (step sweeps) and dual numbers; ``passes`` says whether it holds. ``iterations`` (fixed
    local-global iterations per step, at most 1000) is 30 when not given. ``steps``, ``loss``,
    ``params`` (at least one, each applying to the scene) and the per-step controls are
    checked as ``Scene.grad`` checks them, raising its exceptions; activations left to the
    schedules are checked at the schedules' values."""

def jacobians(seed: int = 2021) -> dict[str, Any]:
    """The ``diffsoft jacobians`` report (joint and ``B = dq/dz`` Jacobians)."""

def mesh_box(
    cells: tuple[int, int, int],
    size: tuple[float, float, float],
    origin: tuple[float, float, float] | None = None,
    split: str = "kuhn",
) -> tuple[_FloatArray, npt.NDArray[np.int64]]:
    """A structured box mesh, ``(vertices (n, 3), tets (m, 4))`` (``diffsoft.mesh.box``); the
    minimum corner at ``origin`` (the origin by default)."""

def _scene_from_state(state: dict[str, Any]) -> Scene:
    """A scene from its pickled state."""

def _run_from_state(positions: Any, velocities: Any, times: Any, stats: Any) -> Run:
    """A run from its pickled state."""

def _trajectory_steps(scene: Scene, steps: int) -> int:
    """``steps`` checked as ``Scene.simulate`` checks it, with the memory of its trajectory."""

def scalar_parameters() -> list[str]:
    """Names of the scalar parameters, from the library's parameter registry (as the CLI's
    ``--param`` and ``--set``; ``diffsoft grad --help`` gives their units)."""

def array_parameters() -> list[tuple[str, str, str]]:
    """``(name, shape, description (unit))`` of the array parameters, from the library's
    parameter registry."""
