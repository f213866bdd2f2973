"""Settings: the robot profile and job settings, read from TOML and validated field by field."""

from cooprint.config.settings import (
    ChunkingSettings,
    JobSettings,
    MeshSettings,
    ProgramSettings,
    RobotProfile,
    SchedulingSettings,
    SlicingSettings,
    load_settings,
    outline_rects,
    robot_profile,
)

__all__ = ["ChunkingSettings", "JobSettings", "MeshSettings", "ProgramSettings", "RobotProfile", "SchedulingSettings", "SlicingSettings",
           "load_settings", "outline_rects",
           "robot_profile"]
