"""Memory the main job will need, estimated before it starts, and the refusal when the machine lacks it.

The main job holds, besides the mechanism, the error model at every grid and verification pose
(about :data:`BYTES_PER_POSE_PARAMETER` bytes per pose and error parameter) and, per Monte Carlo
sample, the kept Δλ and Δα of each distribution (:data:`BYTES_PER_SAMPLE`). The samples are drawn
and evaluated in chunks, so the draws and products take a fixed working set, at most
:data:`CHUNK_BYTES_PER_PARAMETER` bytes per error parameter (a chunk of
:data:`~pkmtol.design.mode_verification.MODE_CHUNK` samples: the parameter draws, the products,
and the maps gathered for the rows outside whole cycles of poses). Measured on the seed robot
(peak RSS, dh set, n = 108, ``pkmtol allocate --no-figures``): 100,000 samples 291 MB and
1,000,000 samples 319 MB (31 bytes per sample) in the ideal mode; 1,000,000 samples 405 MB in the
``none`` mode and 366 MB with an orientation target (before the cyclic products, which lowered the
ideal mode's 1,000,000 to 298 MB). The estimate for 1,000,000 is 467 MB. 6,000 more verification
poses: 273 MB (420 bytes per pose and parameter).

:func:`check_memory` refuses a request whose estimate exceeds :data:`MEMORY_FRACTION` of the
memory available, with :class:`~pkmtol.exceptions.ResourceLimitError` naming the option that
dominates (``samples`` or ``verification_poses``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

import numpy as np

from pkmtol.design.mode_verification import MODE_CHUNK
from pkmtol.error_model.task import machine_parameter_set, probe_sweep
from pkmtol.error_model.tool_sweep import tool_task_grid
from pkmtol.exceptions import ResourceLimitError
from pkmtol.model.mechanism import Mechanism

#: Bytes kept per Monte Carlo sample: Δλ and Δα of each of the three distributions, with a margin.
BYTES_PER_SAMPLE = 64
#: Bytes of a chunk's working set per error parameter (7 doubles per sample and parameter).
CHUNK_BYTES_PER_PARAMETER = 7 * 8 * MODE_CHUNK
#: Bytes per pose (grid or verification) and error parameter (the separation at the pose).
BYTES_PER_POSE_PARAMETER = 450
#: Fixed part (Python, Pinocchio, numpy, the mechanism).
BASE_BYTES = 200e6
#: Share of the available memory a run may plan to use.
MEMORY_FRACTION = 0.8


@dataclass(frozen=True)
class MemoryEstimate:
    """How much memory a run of the main job needs [bytes], by part.

    Attributes:
        samples_bytes: The Monte Carlo samples' part.
        poses_bytes: The grid and verification poses' part.
        base_bytes: The fixed part.
        uncompensatable: Uncompensatable errors ``k`` counted (at four grid points).
        parameters: Error parameters ``n`` of the set.
    """

    samples_bytes: float
    poses_bytes: float
    base_bytes: float
    uncompensatable: int
    parameters: int

    @property
    def total_bytes(self) -> float:
        """The whole estimate [bytes]."""
        return self.samples_bytes + self.poses_bytes + self.base_bytes


def estimate_memory(mechanism: Mechanism, options: Any) -> MemoryEstimate:
    """Estimate the peak memory of ``allocate(mechanism, options)``.

    ``k`` is counted from the error model at four grid points spread over the grid (first to last;
    four inverse kinematics): a symmetric point alone (the centre) can hide some of them.
    """
    pset = machine_parameter_set(mechanism, options.parameter_set)
    grid = mechanism.task_space.grid() if mechanism.tool is None else tool_task_grid(mechanism)[0]
    probe = probe_sweep(mechanism, pset, np.unique(np.linspace(0, len(grid) - 1, 4).astype(int)))
    k = probe.classify().count("uncompensatable")
    n = len(pset)
    samples = int(options.samples)
    poses = len(grid) + min(int(options.verification_poses), samples)
    return MemoryEstimate(
        samples_bytes=float(samples) * BYTES_PER_SAMPLE
        + min(samples, MODE_CHUNK) / MODE_CHUNK * CHUNK_BYTES_PER_PARAMETER * n,
        poses_bytes=float(poses) * BYTES_PER_POSE_PARAMETER * n,
        base_bytes=BASE_BYTES,
        uncompensatable=k,
        parameters=n,
    )


def available_memory() -> float | None:
    """Memory available to a new allocation [bytes] (``MemAvailable``), None if unknown."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    try:
        return float(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None


def check_memory(mechanism: Mechanism, options: Any, available_bytes: float | None = None) -> MemoryEstimate:
    """Refuse a run that would need more than :data:`MEMORY_FRACTION` of the available memory.

    Args:
        mechanism: The mechanism.
        options: The ``DesignOptions``.
        available_bytes: Memory available [bytes] (default: :func:`available_memory`; no check
            when it is unknown).

    Returns:
        The estimate.

    Raises:
        ResourceLimitError: naming ``samples`` or ``verification_poses`` (whichever part is
            larger), with the estimate and what to do.
    """
    est = estimate_memory(mechanism, options)
    avail = available_memory() if available_bytes is None else float(available_bytes)
    if avail is None or est.total_bytes <= MEMORY_FRACTION * avail:
        return est
    if est.samples_bytes >= est.poses_bytes:
        room = MEMORY_FRACTION * avail - est.poses_bytes - est.base_bytes
        fits = max(int((room - CHUNK_BYTES_PER_PARAMETER * est.parameters) / BYTES_PER_SAMPLE), 0)
        raise ResourceLimitError(
            "samples",
            options.samples,
            est.total_bytes,
            avail,
            f"use at most about {fits:,} samples (10,000 give a 0.7 % sampling error on σ[Δλ])",
        )
    raise ResourceLimitError(
        "verification_poses",
        options.verification_poses,
        est.total_bytes,
        avail,
        "use fewer verification poses (2,000 is the default) or a coarser task-space grid",
    )
