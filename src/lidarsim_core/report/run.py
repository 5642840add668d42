"""A *run*: the clouds one scenario produced, plus that scenario, as the report reads them.

A run directory holds

* the scenario that produced the clouds, as ``scenario.yaml`` (or ``.yml``, ``.toml``,
  ``.json``; ``lidarsim demo`` writes it; elsewhere pass it with ``--scenario``), and
* one or more point clouds written by lidarsim, in any format that keeps the frame metadata
  in the file or its sidecar (``.npz``, ``.ply``, ``.pcd``, ``.las``/``.laz``, ``.csv``, see
  :data:`CLOUD_READERS`); when the same frame is there in several formats, the most precise
  is used (``.npz`` first). Other files (e.g. ``lidarsim pattern`` exports) are ignored.

Clouds whose metadata lists no noise model are the run *without errors*, the others the run
*with errors*. When the directory lacks one of the two for the chosen frame, the report
simulates it from the scenario (same seed, same poses): the noiseless twin with ``noise: []``,
the noisy one with the scenario's noise chain, or the datasheet's when that is empty.
"""

from __future__ import annotations

import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..base.errors import ConfigError
from ..geometry.poses import Poses
from ..io.reader import read
from ..pipeline.simulation import Simulation
from ..records.pointcloud import PointCloud
from ..scenario.datasheet import SensorDatasheet
from ..scenario.load import load_scenario
from ..scenario.model import Scenario

#: Scenario file names looked for in a run directory, in order.
SCENARIO_NAMES = ("scenario.yaml", "scenario.yml", "scenario.toml", "scenario.json")


def pose_from_record(record: dict[str, list[float]]) -> Poses:
    """A one-element :class:`~lidarsim_core.geometry.poses.Poses` from a frame-metadata pose record."""
    from scipy.spatial.transform import Rotation

    return Poses(np.asarray(record["translation_m"], dtype=np.float64)[None, :],
                 Rotation.from_quat([record["quaternion_xyzw"]]))


@dataclass
class Run:
    """The clouds of one frame of a run, with the resolved scenario they came from.

    Attributes
    ----------
    directory
        The run directory.
    scenario
        The scenario that produced the clouds.
    simulation
        The scenario resolved (datasheet, scan pattern, target meshes and trajectories).
    frame
        The frame shown.
    noisy, clean
        The clouds with and without the sensor's errors.
    simulated
        Which of ``"with errors"`` / ``"without errors"`` the report simulated itself.
    files
        Cloud files read, by role.
    notes
        Remarks for the reader, e.g. a cloud made by a different configuration.
    """

    directory: Path
    scenario: Scenario
    simulation: Simulation
    frame: int
    noisy: PointCloud
    clean: PointCloud
    simulated: list[str] = field(default_factory=list)
    files: dict[str, Path] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    @property
    def sensor(self) -> SensorDatasheet:
        """The sensor datasheet."""
        return self.simulation.sensor

    def targets_in_sensor(self) -> list[Poses]:
        """Each target's pose in the sensor frame at frame start (body → sensor)."""
        return [pose_from_record(r) for r in self.noisy.frame.targets_in_sensor]

    def targets_in_scene(self) -> list[Poses]:
        """Each target's pose in the scene frame at frame start (body → scene)."""
        return [pose_from_record(r) for r in self.noisy.frame.target_poses_start]

    def sensor_in_scene(self) -> Poses:
        """The sensor's pose in the scene frame at frame start (sensor → scene)."""
        return pose_from_record(self.noisy.frame.sensor_pose_start)


def _is_lidarsim_cloud(path: Path) -> bool:
    if path.suffix.lower() != ".npz":
        return True  # the reader checks the metadata itself
    try:
        with np.load(path, allow_pickle=False) as data:
            return "frame_json" in data.files and "x" in data.files
    except (OSError, ValueError, zipfile.BadZipFile):
        return False


#: Suffixes of the cloud formats a run may hold, most precise first (the order in which the
#: same frame in several formats is chosen); each is read by :func:`lidarsim_core.io.reader.read`.
CLOUD_READERS = (".npz", ".ply", ".pcd", ".las", ".laz", ".csv")


def read_run_clouds(directory: Path) -> dict[Path, PointCloud]:
    """Every lidarsim cloud in ``directory``, most precise format first.

    Files that are not lidarsim clouds are skipped; an ``.npz`` that says it is one (it holds
    ``frame_json``) but cannot be read is an error naming it, not a silent gap in the run.
    """
    from ..base.config_io import check_input_file

    order = list(CLOUD_READERS)
    paths = sorted((p for p in directory.iterdir()
                    if p.is_file() and p.suffix.lower() in CLOUD_READERS),
                   key=lambda p: (order.index(p.suffix.lower()), p.name))
    clouds = {}
    for path in paths:
        if not _is_lidarsim_cloud(path):
            continue
        check_input_file(path, "point cloud", limit_name="data_bytes")
        try:
            clouds[path] = read(path)
        except (ConfigError, ImportError, OSError, ValueError, KeyError, TypeError,
                AttributeError, EOFError, zipfile.BadZipFile) as exc:
            if path.suffix.lower() != ".npz":
                continue  # not a lidarsim cloud (or LAS without laspy): not part of the run
            if isinstance(exc, ConfigError):  # the reader's own line already names the file
                raise ConfigError(f"cannot read this lidarsim cloud: {exc.message}",
                                  source=path, field="frame_json") from None
            raise ConfigError(f"cannot read this lidarsim cloud: {type(exc).__name__}: "
                              f"{' '.join(str(exc).split())}", source=path,
                              field="frame_json") from None
    return clouds


def find_scenario(directory: Path) -> Path:
    """The scenario file of a run directory (raises ConfigError naming the directory)."""
    for name in SCENARIO_NAMES:
        if (directory / name).is_file():
            return directory / name
    raise ConfigError(f"no scenario file in the run directory (looked for "
                      f"{', '.join(SCENARIO_NAMES)}); pass it with --scenario", source=directory)


def load_run(directory: str | Path, *, scenario: str | Path | None = None,
             frame: int | None = None, complete: bool = True) -> Run:
    """Read a run directory (see the module docstring).

    Parameters
    ----------
    directory
        The run directory.
    scenario
        The scenario file, when it is not in ``directory``.
    frame
        The frame to show (default: the lowest frame with a cloud).
    complete
        Simulate the missing twin (with / without errors) from the scenario. When False, a
        missing twin is an error.

    Raises
    ------
    ConfigError
        Naming the directory when it holds no lidarsim cloud or scenario, or when the clouds
        and the scenario disagree (different sensor).
    """
    directory = Path(directory)
    if not directory.is_dir():
        raise ConfigError("the run must be a directory of clouds and their scenario",
                          source=directory)
    scenario_path = Path(scenario) if scenario is not None else find_scenario(directory)
    scen = load_scenario(scenario_path)
    clouds = read_run_clouds(directory)
    if not clouds:
        raise ConfigError(f"no point cloud written by lidarsim ({', '.join(CLOUD_READERS)}) in "
                          "the run directory; write one with `lidarsim simulate ... --out "
                          "DIR/cloud.npz`", source=directory)
    frames = sorted({c.frame.frame for c in clouds.values()})
    chosen = frames[0] if frame is None else frame
    if chosen not in frames:
        raise ConfigError(f"no cloud of frame {chosen} in the run; frames present: {frames}",
                          source=directory, field="--frame")
    sim = Simulation(scen)
    roles: dict[str, tuple[Path, PointCloud]] = {}
    for path, cloud in clouds.items():
        if cloud.frame.frame != chosen:
            continue
        if cloud.frame.sensor != sim.sensor.name:
            raise ConfigError(f"cloud {path.name} was made by sensor '{cloud.frame.sensor}' but "
                              f"the scenario uses '{sim.sensor.name}'", source=scenario_path,
                              field="sensor.datasheet")
        roles.setdefault("with errors" if cloud.frame.noise else "without errors", (path, cloud))
    notes = _configuration_notes(scen, roles)
    simulated = []
    for role in ("with errors", "without errors"):
        if role in roles:
            continue
        if not complete:
            raise ConfigError(f"the run has no cloud {role} for frame {chosen}", source=directory)
        roles[role] = (scenario_path, _simulate_twin(scen, chosen, noisy=role == "with errors"))
        simulated.append(role)
    return Run(directory, scen, sim, chosen, roles["with errors"][1], roles["without errors"][1],
               simulated, {role: path for role, (path, _) in roles.items()
                           if role not in simulated}, notes)


def _configuration_notes(scenario: Scenario, roles: dict[str, tuple[Path, PointCloud]]
                         ) -> list[str]:
    """Say when a cloud was not made by this scenario (its configuration hash differs).

    The cloud without errors is compared with the scenario run with ``noise: []``.
    """
    notes = []
    for role, (path, cloud) in roles.items():
        expected = scenario if role == "with errors" else scenario.with_updates(noise=[])
        if cloud.frame.config_hash != expected.config_hash():
            notes.append(f"{path.name} was made by a configuration other than the scenario's "
                         f"(hash {cloud.frame.config_hash}, scenario "
                         f"{expected.config_hash()}): the figures may not match each other.")
    return notes


def _simulate_twin(scenario: Scenario, frame: int, *, noisy: bool) -> PointCloud:
    """The same frame with the scenario's (or the datasheet's) errors, or with none."""
    if noisy:
        chain = scenario.noise if scenario.noise else None  # None: the datasheet's errors
        twin = scenario.with_updates(noise=None if chain is None else
                                     [c.model_dump() for c in chain])
    else:
        twin = scenario.with_updates(noise=[])
    return Simulation(twin).run_frame(frame)
