"""Scenario settings: what to simulate, validated by pydantic and loaded from YAML/TOML/JSON.

Settings only: nothing here imports an implementation (an import-linter contract holds it).
"""

from .demo import demo_scenario, demo_target_pose
from .load import as_scenario, load_scenario, scenario_from_dict
from .model import (
                    MeshConfig,
                    NamedComponent,
                    ScanConfig,
                    Scenario,
                    SensorConfig,
                    TargetConfig,
                    TrajectoryConfig,
)
from .pose import PoseConfig

__all__ = ["MeshConfig", "NamedComponent", "PoseConfig", "ScanConfig", "Scenario", "SensorConfig",
           "TargetConfig", "TrajectoryConfig", "as_scenario", "demo_scenario", "demo_target_pose",
           "load_scenario", "scenario_from_dict"]
