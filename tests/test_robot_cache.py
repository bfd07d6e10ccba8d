"""``pkmtol calibrate`` keeps a loaded robot and its grid sweep only while the robot's files are unchanged."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from pkmtol.cli import robot_cache
from pkmtol.error_model.parameters import parameter_set

SEED = Path(__file__).resolve().parents[1] / "robots" / "r2rps_ups"


def test_a_robot_is_loaded_again_when_one_of_its_files_changes(tmp_path) -> None:
    folder = tmp_path / "robot"
    shutil.copytree(SEED, folder)
    robot_cache.clear()
    first = robot_cache.mechanism(folder)
    assert robot_cache.mechanism(folder) is first  # unchanged: the same mechanism
    grid = robot_cache.robot_grid(first, parameter_set(first, "urdf"))
    assert robot_cache.robot_grid(first, parameter_set(first, "urdf")) is grid
    assert robot_cache.robot_grid(first, parameter_set(first, "dh")) is not grid  # per parameter set
    toml = folder / "mechanism.toml"
    text = toml.read_text(encoding="utf-8")
    assert 'name = "r2rps_ups"' in text
    toml.write_text(text.replace('name = "r2rps_ups"', 'name = "renamed"', 1), encoding="utf-8")
    again = robot_cache.mechanism(folder)
    assert again is not first and again.name == "renamed"
    urdf = folder / "limb4.urdf"  # a limb's file, same size, only its time changed
    st = urdf.stat()
    os.utime(urdf, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    assert robot_cache.mechanism(folder) is not again
    robot_cache.clear()
