# ruff: noqa: E501  (the target table: one call per line)
"""A seeded fuzzer of the Python API: every public callable, one bad argument at a time.

Each target (:data:`TARGETS`) names a public function, constructor or method and builds one good
call of it from shared fixtures (:class:`Fixtures`: the seed robot, its hybrid variant, its loop
tree, a small allocation, each made once). A case replaces exactly one argument of that call by a
bad value (:func:`bad_values`: wrong types, ``None``, strings for numbers, NaN/inf, 1e308,
out-of-range numbers, empty and wrongly shaped arrays, another fixture object) and calls it. The
outcome is ``ok`` (accepted), the name of the :class:`~pkmtol.exceptions.PkmtolError` raised, or
``BUG`` for any other exception, kept with the place it was raised from.

Used by ``tests/test_api_fuzz.py`` (a seeded subset in CI) and ``scripts/fuzz_api.py`` (all cases).
"""

from __future__ import annotations

import inspect
import os
import random
import signal
import tempfile
import time
import traceback
import warnings
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

import pkmtol
from pkmtol.exceptions import PkmtolError

REPO = Path(__file__).resolve().parents[1]
ROBOTS = REPO / "robots"
DATA = REPO / "tests" / "data"
#: A call taking longer than this [s] is a hang.
HANG_S = 20.0
NAN, INF = float("nan"), float("inf")


class _Marker:
    """An object of no type pkmtol knows."""

    def __repr__(self) -> str:
        return "<object>"


class Fixtures:
    """The good arguments, each built once on first use (cheap options, few poses)."""

    def __init__(self, tmp: Path) -> None:
        self.tmp = tmp

    @cached_property
    def mech(self) -> pkmtol.Mechanism:
        return pkmtol.load_mechanism(ROBOTS / "r2rps_ups")

    @cached_property
    def chain(self) -> pkmtol.ClosedChain:
        return pkmtol.ClosedChain(self.mech)

    @cached_property
    def q_home(self) -> np.ndarray:
        return self.chain.home()

    @cached_property
    def target(self) -> np.ndarray:
        return self.mech.task_space.grid()[0].copy()

    @cached_property
    def pose(self) -> pkmtol.Pose:
        return self.chain.inverse(self.target)

    @cached_property
    def u(self) -> np.ndarray:
        return self.pose.q_all[self.chain.actuated_idx].copy()

    @cached_property
    def pset(self) -> pkmtol.ParameterSet:
        return pkmtol.parameter_set(self.mech, "urdf")

    @cached_property
    def points(self) -> np.ndarray:
        return self.mech.task_space.grid()[:3].copy()

    @cached_property
    def grid(self) -> pkmtol.Sweep:
        return pkmtol.sweep(self.mech, self.pset, self.points, chain=self.chain)

    @cached_property
    def options(self) -> pkmtol.DesignOptions:
        return pkmtol.DesignOptions(samples=200, verification_poses=20, exact_samples=0, claim_poses=5)

    @cached_property
    def result(self) -> pkmtol.DesignResult:
        return pkmtol.allocate(self.mech, self.options)

    @cached_property
    def eta(self) -> np.ndarray:
        return np.full(len(self.pset.parameters), 1e-6)

    @cached_property
    def limb_eps(self) -> list[np.ndarray]:
        return self.pset.perturbation(self.eta, self.mech)[0]

    @cached_property
    def models(self) -> list[Any]:
        return [lb.model for lb in self.mech.limbs]

    @cached_property
    def constrained(self) -> pkmtol.ConstrainedModel:
        return self.mech.constraint_models()

    @cached_property
    def hybrid(self) -> pkmtol.Mechanism:
        return pkmtol.load_mechanism(ROBOTS / "r2rps_ups_wrist")

    @cached_property
    def hchain(self) -> pkmtol.HybridChain:
        return pkmtol.HybridChain(self.hybrid)

    @cached_property
    def hhome(self) -> pkmtol.HybridPose:
        return self.hchain.home()

    @cached_property
    def hpset(self) -> pkmtol.HybridParameterSet:
        return pkmtol.hybrid_parameter_set(self.hybrid)

    @cached_property
    def tcp(self) -> np.ndarray:
        return self.hhome.oMt.translation.copy()

    @cached_property
    def axis(self) -> np.ndarray:
        return self.hhome.oMt.rotation[:, 2].copy()

    @cached_property
    def tree(self) -> pkmtol.LoopTree:
        return pkmtol.tree_from_mechanism(self.mech)[0]

    @cached_property
    def tparams(self) -> pkmtol.TreeParameters:
        return pkmtol.tree_urdf_set(self.tree)

    @cached_property
    def tbatch(self) -> pkmtol.TreeBatch:
        return pkmtol.TreeBatch(self.tree)

    @cached_property
    def tchain(self) -> pkmtol.TreeChain:
        return pkmtol.TreeChain(self.tree)

    @cached_property
    def tguesses(self) -> np.ndarray:
        return np.tile(self.tchain.home(), (len(self.points), 1))

    @cached_property
    def tsols(self) -> Any:
        return self.tbatch.inverse(self.points, self.tguesses)

    @cached_property
    def signoff(self) -> pkmtol.SignOff:
        return pkmtol.sign_off(self.result)

    @cached_property
    def task(self) -> pkmtol.TaskSpace:
        return self.mech.task_space

    @cached_property
    def out(self) -> Path:
        folder = self.tmp / "out"
        folder.mkdir(exist_ok=True)
        return folder

    @cached_property
    def a_file(self) -> Path:
        """A file that is no input of any call (a path in place of a folder or another file)."""
        path = self.tmp / "a_file.txt"
        path.write_text("not a robot\n", encoding="utf-8")
        return path

    def fresh_dir(self) -> Path:
        return Path(tempfile.mkdtemp(dir=self.tmp))


@dataclass(frozen=True)
class Target:
    """One public callable and a good call of it.

    Attributes:
        name: How the API spells it (``ClosedChain.inverse``).
        build: ``fixtures → (callable, positional args, keyword args)``: a call that succeeds.
        heavy: The call runs a whole design when it accepts its arguments (fewer cases in CI).
    """

    name: str
    build: Callable[[Fixtures], tuple[Callable[..., Any], list[Any], dict[str, Any]]]
    heavy: bool = False


def _t(name: str, heavy: bool = False) -> Callable[[Callable], Target]:
    def wrap(build: Callable) -> Target:
        return Target(name, build, heavy)

    return wrap


def _call(
    fn: Callable[..., Any], *args: Any, **kwargs: Any
) -> tuple[Callable[..., Any], list[Any], dict[str, Any]]:
    return fn, list(args), kwargs


TASK = dict(kind="cylinder", radius_m=0.6, z_range_m=(0.9, 1.1), layers=3, rings=(8, 16, 24))
CLOSED_HOME = {"limb1_u1": 0.32175, "limb1_p3": 0.79057, "limb1_s6": -0.32175, "limb2_r2": 0.2606, "limb2_p3": 0.77621, "limb2_s6": -0.2606, "limb3_r2": -0.2606, "limb3_p3": 0.77621, "limb3_s6": 0.2606, "limb4_p3": 0.75}  # fmt: skip
HOMES = [[0.32175, 0, 0.79057, 0, 0, -0.32175], [0, 0.2606, 0.77621, 0, 0, -0.2606], [0, -0.2606, 0.77621, 0, 0, 0.2606], [0, 0, 0.75]]  # fmt: skip


def _targets() -> list[Target]:  # noqa: C901 (one table)
    T: list[Target] = []
    add = T.append
    P = pkmtol
    # --- model: loading and building mechanisms
    add(
        Target(
            "load_mechanism",
            lambda f: _call(
                P.load_mechanism, ROBOTS / "r2rps_ups", doc=None, urdf_texts=None, check_home_closure=True
            ),
        )
    )
    add(
        Target(
            "load_closed_loop",
            lambda f: _call(
                P.load_closed_loop,
                DATA / "r2rps_ups_closed" / "robot.urdf",
                DATA / "r2rps_ups_closed" / "robot.yaml",
                reference_point_m=[0.0, 0.0, 0.3],
                task_space=f.task,
                name="c",
                platform_link=None,
                limb_names=None,
                home=dict(CLOSED_HOME),
                target_m=5e-5,
                betas=(0.5, 2.0),
                design_beta=2.0,
                description="",
            ),
        )
    )
    add(
        Target(
            "closed_loop_limbs",
            lambda f: _call(
                P.closed_loop_limbs,
                DATA / "r2rps_ups_closed" / "robot.urdf",
                DATA / "r2rps_ups_closed" / "robot.yaml",
                platform_link=None,
                limb_names=None,
                home=None,
            ),
        )
    )
    add(
        Target(
            "load_mjcf",
            lambda f: _call(
                P.load_mjcf,
                DATA / "r2rps_ups_mjcf" / "robot.xml",
                reference_point_m=[0.0, 0.0, 0.3],
                task_space=f.task,
                name="m",
                platform_link=None,
                limb_names=["limb1", "limb2", "limb3", "limb4"],
                home=None,
                keyframe="home",
                actuated=None,
                target_m=5e-5,
                betas=(0.5, 2.0),
                design_beta=2.0,
                description="",
            ),
        )
    )
    add(
        Target(
            "mjcf_limbs",
            lambda f: _call(
                P.mjcf_limbs,
                DATA / "r2rps_ups_mjcf" / "robot.xml",
                platform_link=None,
                limb_names=["limb1", "limb2", "limb3", "limb4"],
                home=None,
                keyframe="home",
                actuated=None,
            ),
        )
    )
    add(
        Target(
            "tree_from_mjcf",
            lambda f: _call(
                P.tree_from_mjcf,
                DATA / "digit_like_leg" / "robot.xml",
                task_frame="toe",
                point_m=(0.0, 0.0, 0.0),
                platform_frame=None,
                actuated=None,
                keyframe=None,
                home=None,
            ),
        )
    )
    add(
        Target(
            "tree_from_urdf",
            lambda f: _call(
                P.tree_from_urdf,
                ROBOTS / "delta_epr" / "robot.urdf",
                None,
                task_frame="platform",
                point_m=(0.0, 0.0, 0.0),
                platform_frame=None,
                actuated=None,
                home=None,
                name=None,
            ),
        )
    )
    add(
        Target(
            "tree_from_constraint_models",
            lambda f: _call(
                P.tree_from_constraint_models,
                f.constrained.model,
                list(f.constrained.constraints),
                _actuated_names(f),
                _platform_frame_name(f),
                (0.0, 0.0, 0.3),
                platform_frame=None,
                home=f.constrained.q([lb.home for lb in f.mech.limbs]),
                name="t",
            ),
        )
    )
    add(Target("tree_from_mechanism", lambda f: _call(P.tree_from_mechanism, f.mech, None)))
    add(Target("constraint_models", lambda f: _call(P.constraint_models, f.mech, None)))
    add(
        Target(
            "Mechanism.from_models",
            lambda f: _call(
                P.Mechanism.from_models,
                "m",
                f.models,
                [["limb1_p3"], ["limb2_p3"], ["limb3_p3"], []],
                "platform",
                [0.0, 0.0, 0.3],
                f.task,
                limb_names=None,
                homes=HOMES,
                target_m=5e-5,
                betas=(0.5, 2.0),
                design_beta=2.0,
            ),
        )
    )
    add(
        Target(
            "Mechanism.from_limbs",
            lambda f: _call(
                P.Mechanism.from_limbs,
                "m",
                list(f.mech.limbs),
                [0.0, 0.0, 0.3],
                f.task,
                target_m=5e-5,
                betas=(0.5, 2.0),
                design_beta=2.0,
                root=None,
                description="",
                extra=None,
                check_home_closure=True,
                task_normal=None,
            ),
        )
    )
    add(
        Target(
            "Mechanism.from_constraint_models",
            lambda f: _call(
                P.Mechanism.from_constraint_models,
                f.constrained.model,
                list(f.constrained.constraints),
                _actuated_names(f),
                _platform_frame_name(f),
                reference_point_m=(0.0, 0.0, 0.3),
                task_space=f.task,
                name="c",
                home=f.constrained.q([lb.home for lb in f.mech.limbs]),
                limb_names=None,
                target_m=5e-5,
                betas=(0.5, 2.0),
                design_beta=2.0,
            ),
        )
    )
    add(Target("Mechanism.limb", lambda f: _call(f.mech.limb, "limb1")))
    add(Target("Mechanism.constraint_models", lambda f: _call(f.mech.constraint_models, None)))
    add(Target("Mechanism.task_error", lambda f: _call(f.mech.task_error, np.array([1e-6, 2e-6, 3e-6]))))
    add(Target("Mechanism.loop_tree", lambda f: _call(f.mech.loop_tree)))
    add(Target("TaskSpace", lambda f: _call(P.TaskSpace, **TASK, center_xy_m=(0.0, 0.0), points_m=None)))
    add(Target("TaskSpace.grid", lambda f: _call(f.task.grid)))
    add(Target("TaskSpace.on_rim", lambda f: _call(f.task.on_rim)))
    add(Target("TaskSpace.sample", lambda f: _call(f.task.sample, np.random.default_rng(0), 5)))
    add(
        Target(
            "ToolDirections",
            lambda f: _call(P.ToolDirections, (0.0, 0.0, 1.0), half_angle_rad=0.2, rings=(4,)),
        )
    )
    add(Target("ToolDirections.grid", lambda f: _call(P.ToolDirections((0.0, 0.0, 1.0), 0.2, (4,)).grid)))
    add(
        Target(
            "ToolDirections.sample",
            lambda f: _call(P.ToolDirections((0.0, 0.0, 1.0), 0.2, (4,)).sample, np.random.default_rng(0), 5),
        )
    )
    add(
        Target(
            "DrawingSettings",
            lambda f: _call(
                P.DrawingSettings,
                convention="normal",
                k=3.0,
                feature_length_m=0.1,
                feature_lengths_m={},
                nominals_m={},
            ),
        )
    )
    add(
        Target(
            "DrawingSettings.feature_length", lambda f: _call(P.DrawingSettings().feature_length, "limb1_p3")
        )
    )
    add(
        Target(
            "DrawingSettings.with_convention",
            lambda f: _call(P.DrawingSettings().with_convention, "normal", 2.0),
        )
    )
    add(Target("Tool.as_limb", lambda f: _call(f.hybrid.tool.as_limb, None)))
    add(Target("Tool.with_length", lambda f: _call(f.hybrid.tool.with_length, 0.15)))
    add(Target("Tool.with_locked", lambda f: _call(f.hybrid.tool.with_locked, {})))
    # --- kinematics
    add(Target("ClosedChain", lambda f: _call(P.ClosedChain, f.mech, None, True)))
    add(Target("ClosedChain.home", lambda f: _call(f.chain.home)))
    add(Target("ClosedChain.inverse", lambda f: _call(f.chain.inverse, f.target.copy(), f.q_home.copy())))
    add(
        Target("ClosedChain.forward", lambda f: _call(f.chain.forward, f.u.copy(), f.pose.q_all.copy(), None))
    )
    add(
        Target(
            "ClosedChain.platform_placements", lambda f: _call(f.chain.platform_placements, f.q_home.copy())
        )
    )
    add(Target("ClosedChain.predict", lambda f: _call(f.chain.predict, f.pose, f.target + 1e-3)))
    add(
        Target(
            "ClosedChain.limit_violation",
            lambda f: _call(f.chain.limit_violation, f.q_home.copy(), f.target.copy()),
        )
    )
    add(Target("ClosedChain.worst_limb", lambda f: _call(f.chain.worst_limb, f.q_home.copy())))
    add(Target("ClosedChain.worst_loop", lambda f: _call(f.chain.worst_loop, f.q_home.copy())))
    add(Target("ClosedChain.mobility", lambda f: _call(f.chain.mobility)))
    add(Target("perturbed_limb_models", lambda f: _call(P.perturbed_limb_models, f.mech, f.limb_eps)))
    add(Target("HybridChain", lambda f: _call(P.HybridChain, f.hybrid, None, None, True)))
    add(Target("HybridChain.home", lambda f: _call(f.hchain.home)))
    add(
        Target(
            "HybridChain.inverse",
            lambda f: _call(f.hchain.inverse, f.tcp + [0.0, 0.0, 1e-3], f.axis.copy(), None),
        )
    )
    add(
        Target(
            "HybridChain.inverse_many",
            lambda f: _call(f.hchain.inverse_many, np.array([f.tcp]), np.array([f.axis]), [f.hhome]),
        )
    )
    add(
        Target(
            "HybridChain.evaluate", lambda f: _call(f.hchain.evaluate, f.hhome.module, f.hhome.q_tool.copy())
        )
    )
    add(
        Target(
            "HybridChain.forward",
            lambda f: _call(
                f.hchain.forward,
                f.hhome.module.q_all[f.hchain.chain.actuated_idx],
                f.hhome.q_tool.copy(),
                f.hhome.module.q_all.copy(),
                None,
                None,
            ),
        )
    )
    add(
        Target(
            "HybridChain.limit_violation",
            lambda f: _call(f.hchain.limit_violation, f.hhome.q_tool.copy(), f.tcp.copy()),
        )
    )
    add(Target("TreeBatch", lambda f: _call(P.TreeBatch, f.tree, True)))
    add(Target("TreeBatch.inverse", lambda f: _call(f.tbatch.inverse, f.points.copy(), f.tguesses.copy())))
    add(
        Target(
            "TreeBatch.forward",
            lambda f: _call(
                f.tbatch.forward, f.tsols.q[:, list(f.tree.actuated)].copy(), f.tsols.q.copy(), None
            ),
        )
    )
    add(
        Target(
            "TreeBatch.predict",
            lambda f: _call(f.tbatch.predict, f.tsols, np.arange(len(f.points)), f.points + 1e-3),
        )
    )
    add(Target("TreeBatch.system", lambda f: _call(f.tbatch.system, f.tsols.q.copy(), f.points.copy())))
    add(Target("TreeBatch.worst_loop", lambda f: _call(f.tbatch.worst_loop, f.tsols.q[0].copy())))
    add(
        Target(
            "TreeBatch.limit_violation",
            lambda f: _call(f.tbatch.limit_violation, f.tsols.q[0].copy(), f.points[0].copy()),
        )
    )
    add(Target("TreeChain", lambda f: _call(P.TreeChain, f.tree)))
    add(Target("TreeChain.home", lambda f: _call(f.tchain.home)))
    add(Target("TreeChain.inverse", lambda f: _call(f.tchain.inverse, f.points[0].copy(), None)))
    add(
        Target(
            "TreeChain.forward",
            lambda f: _call(
                f.tchain.forward, f.tsols.q[0, list(f.tree.actuated)].copy(), f.tsols.q[0].copy(), None
            ),
        )
    )
    add(Target("LoopTree.support", lambda f: _call(f.tree.support, f.tree.task_frame)))
    add(Target("LoopTree.moved_by", lambda f: _call(f.tree.moved_by, f.tree.task_frame)))
    add(Target("LoopTree.raw_block", lambda f: _call(f.tree.raw_block, "joint", 0)))
    add(
        Target(
            "ConstrainedModel.q", lambda f: _call(f.constrained.q, [lb.home.copy() for lb in f.mech.limbs])
        )
    )
    add(
        Target(
            "ConstrainedModel.residuals",
            lambda f: _call(f.constrained.residuals, f.constrained.q(list(f.pose.q)), None),
        )
    )
    add(
        Target(
            "ConstrainedModel.jacobian",
            lambda f: _call(f.constrained.jacobian, f.constrained.q(list(f.pose.q)), None),
        )
    )
    add(Target("ConstrainedModel.constraint_vector", lambda f: _call(f.constrained.constraint_vector)))
    add(Target("ConstrainedModel.rigid_constraints", lambda f: _call(f.constrained.rigid_constraints)))
    add(Target("PointTask", lambda f: _call(P.PointTask, np.array([0.0, 0.0, 0.3]), None)))
    add(
        Target(
            "PointTask.projection",
            lambda f: _call(P.PointTask(np.array([0.0, 0.0, 0.3]), np.array([0.0, 0.0, 1.0])).projection),
        )
    )
    add(Target("PointTask.position", lambda f: _call(_point_task().position, np.eye(4)[None].copy())))
    add(
        Target(
            "PointTask.residual",
            lambda f: _call(_point_task().residual, np.eye(4)[None].copy(), np.zeros((1, 3))),
        )
    )
    add(
        Target(
            "PointTask.jacobian",
            lambda f: _call(_point_task().jacobian, np.eye(4)[None].copy(), np.ones((1, 6, 2))),
        )
    )
    add(Target("PointTask.of_twist", lambda f: _call(_point_task().of_twist, np.zeros((1, 3)))))
    # --- error model
    add(Target("parameter_set", lambda f: _call(P.parameter_set, f.mech, "urdf")))
    add(Target("default_set", lambda f: _call(P.default_set, f.mech)))
    add(Target("ParameterSet.perturbation", lambda f: _call(f.pset.perturbation, f.eta.copy(), f.mech)))
    add(
        Target(
            "ParameterSet.perturbations",
            lambda f: _call(f.pset.perturbations, np.tile(f.eta, (2, 1)), f.mech),
        )
    )
    add(Target("separate", lambda f: _call(P.separate, f.mech, f.pset, f.chain, f.pose, False)))
    add(
        Target(
            "sweep",
            lambda f: _call(
                P.sweep, f.mech, f.pset, f.points.copy(), chain=f.chain, guesses=None, progress=False
            ),
        )
    )
    add(Target("Sweep.classify", lambda f: _call(f.grid.classify)))
    add(Target("Sweep.incompatible", lambda f: _call(f.grid.incompatible)))
    add(Target("error_table", lambda f: _call(P.error_table, f.mech, "urdf", None, False), heavy=True))
    add(Target("ErrorTable.to_json", lambda f: _call(_error_table(f).to_json)))
    add(Target("sensitivities", lambda f: _call(P.sensitivities, f.grid.J[0].copy())))
    add(Target("norm_moments", lambda f: _call(P.norm_moments, np.array([1.0, 2.0, 3.0]))))
    add(Target("hybrid_parameter_set", lambda f: _call(P.hybrid_parameter_set, f.hybrid, "urdf")))
    add(Target("HybridParameterSet.module_set", lambda f: _call(f.hpset.module_set)))
    add(
        Target(
            "HybridParameterSet.perturbation",
            lambda f: _call(f.hpset.perturbation, np.full(len(f.hpset.parameters), 1e-6), f.hybrid),
        )
    )
    add(
        Target(
            "HybridParameterSet.perturbations",
            lambda f: _call(f.hpset.perturbations, np.full((2, len(f.hpset.parameters)), 1e-6), f.hybrid),
        )
    )
    add(Target("HybridParameterSet.sub_assembly", lambda f: _call(f.hpset.sub_assembly, 0)))
    add(
        Target(
            "HybridParameterSet.tool_raw",
            lambda f: _call(f.hpset.tool_raw, np.full(len(f.hpset.parameters), 1e-6)),
        )
    )
    add(
        Target(
            "hybrid_sweep",
            lambda f: _call(
                P.hybrid_sweep,
                f.hybrid,
                f.hpset,
                np.array([f.tcp]),
                np.array([f.axis]),
                chain=f.hchain,
                scope="machine",
                guesses=None,
                progress=False,
            ),
        )
    )
    add(Target("ToolSweep.classify", lambda f: _call(_tool_sweep(f).classify)))
    add(Target("ToolSweep.incompatible", lambda f: _call(_tool_sweep(f).incompatible)))
    add(Target("tree_urdf_set", lambda f: _call(P.tree_urdf_set, f.tree)))
    add(Target("TreeParameters.raw", lambda f: _call(f.tparams.raw, np.full(len(f.tparams.names), 1e-6))))
    add(
        Target(
            "tree_sweep",
            lambda f: _call(
                P.tree_sweep, f.tree, f.tparams, f.points.copy(), batch=f.tbatch, guesses=None, general=False
            ),
        )
    )
    add(
        Target("separate_tree", lambda f: _call(P.separate_tree, f.tree, f.tparams, f.tsols, f.tbatch, False))
    )
    add(Target("frame_maps", lambda f: _call(P.frame_maps, f.tree, f.tsols.q[0].copy(), f.tree.task_frame)))
    # --- design
    add(
        Target(
            "DesignOptions",
            lambda f: _call(
                P.DesignOptions,
                target_m=5e-5,
                betas=(0.5, 2.0),
                design_beta=2.0,
                parameter_set="urdf",
                samples=200,
                verification_poses=20,
                exact_samples=0,
                seed=0,
                progress=False,
                method="fosm",
                criterion="every",
                claim_poses=5,
                compensation="ideal",
                calibration=None,
                orientation_target_rad=None,
                tool_axis=None,
                executor=None,
                drawing=None,
            ),
        )
    )
    add(Target("allocate", lambda f: _call(P.allocate, f.mech, f.options), heavy=True))
    add(
        Target(
            "fosm_tolerances",
            lambda f: _call(
                P.fosm_tolerances, np.array([1.0, 2.0, 0.5]), 5e-5, np.array([1.0, 2.0]), noise_variance=0.0
            ),
        )
    )
    add(Target("reliability_fosm", lambda f: _call(P.reliability_fosm, np.array([1.0, 2.0]))))
    add(
        Target(
            "exact_reliability",
            lambda f: _call(P.exact_reliability, np.diag([1e-10, 2e-10, 3e-10]), 5e-5, gradient=False),
        )
    )
    add(
        Target(
            "search_sensitive_pose",
            lambda f: _call(P.search_sensitive_pose, _unc_J(f), 50, np.random.default_rng(0)),
        )
    )
    add(
        Target(
            "verify",
            lambda f: _call(
                P.verify,
                f.mech,
                f.pset,
                f.grid,
                _columns(f),
                _sigma(f),
                5e-5,
                _distribution(f),
                50,
                0,
                np.random.default_rng(0),
                progress=False,
                executor=None,
            ),
        )
    )
    add(Target("method_design_for", lambda f: _method_design_call(f), heavy=True))
    add(Target("sign_off", lambda f: _call(P.sign_off, f.result)))
    # --- present
    add(Target("summary_text", lambda f: _call(P.summary_text, f.result, markdown=False, units="mm")))
    add(Target("to_json", lambda f: _call(P.to_json, f.result)))
    add(
        Target(
            "write_outputs",
            lambda f: _call(P.write_outputs, f.result, f.fresh_dir(), extra=None, figures=False, units="mm"),
        )
    )
    add(
        Target(
            "write_report",
            lambda f: _call(
                P.write_report, f.result, f.fresh_dir() / "r.html", prov=None, scene_options=None
            ),
            heavy=True,
        )
    )
    return T


# --- small helpers of the target table -------------------------------------------------------


def _actuated_names(f: Fixtures) -> list[str]:
    names = []
    for limb in f.mech.limbs:
        names += [limb.joint_names[a] for a in limb.actuated]
    return names


def _platform_frame_name(f: Fixtures) -> str:
    cm = f.constrained
    return str(cm.model.frames[cm.platform_frames[0]].name)


def _error_table(f: Fixtures) -> pkmtol.ErrorTable:
    if "_table" not in f.__dict__:
        f.__dict__["_table"] = pkmtol.error_table(f.mech, "urdf")
    return f.__dict__["_table"]


def _point_task() -> pkmtol.PointTask:
    return pkmtol.PointTask(np.array([0.0, 0.0, 0.3]))


def _tool_sweep(f: Fixtures) -> pkmtol.ToolSweep:
    if "_tool_sweep" not in f.__dict__:
        f.__dict__["_tool_sweep"] = pkmtol.hybrid_sweep(
            f.hybrid, f.hpset, np.array([f.tcp]), np.array([f.axis]), chain=f.hchain
        )
    return f.__dict__["_tool_sweep"]


def _unc_J(f: Fixtures) -> np.ndarray:
    return f.grid.J.copy()


def _columns(f: Fixtures) -> np.ndarray:
    return f.result.uncompensatable.copy()


def _sigma(f: Fixtures) -> np.ndarray:
    """The design-β tolerances of the allocated parameters [m, rad]."""
    r = f.result
    return r.tolerances[r.uncompensatable, list(r.betas).index(r.design_beta)].copy()


def _distribution(f: Fixtures) -> str:
    return next(iter(f.result.verification))


def _method_design_call(f: Fixtures) -> tuple[Callable[..., Any], list[Any], dict[str, Any]]:
    r = f.result
    opt = pkmtol.DesignOptions(
        method="exact", samples=200, verification_poses=20, exact_samples=0, claim_poses=5
    )
    return _call(
        pkmtol.method_design_for,
        f.mech,
        f.pset,
        r.grid,
        r.uncompensatable,
        _sigma(f),
        r.target_m,
        r.design_beta,
        r.worst_index,
        opt,
        maps=None,
        orientation=None,
    )


TARGETS: list[Target] = _targets()


# --- the bad values ---------------------------------------------------------------------------

GENERIC: list[Any] = [
    None,
    "x",
    "1 mm",
    True,
    5,
    -1,
    0,
    2.5,
    1e308,
    -1e308,
    NAN,
    INF,
    10**30,
    [],
    (),
    {},
    _Marker(),
    b"\xff",
]


def bad_values(good: Any, fx: Fixtures) -> list[Any]:
    """Values to put in place of ``good``: the generic ones and some shaped like ``good``."""
    out = list(GENERIC)
    if isinstance(good, np.ndarray) and good.dtype.kind in "fi" and good.size:
        out += [np.full(good.shape, NAN), np.full(good.shape, INF), np.full(good.shape, 1e308),
                good.ravel()[:-1].copy(), np.zeros((0,) + good.shape[1:]), good[None].copy(),
                good.astype(str), -np.abs(good) - 1.0, np.zeros(good.shape, dtype=complex)]  # fmt: skip
        if good.ndim == 2:
            out += [good.T.copy(), good[:, :-1].copy()]
    elif isinstance(good, bool):
        out += ["yes", 1.0, np.bool_(True)]
    elif isinstance(good, int):
        out += [10**12, -(10**12), 3.0, "5", np.int64(2)]
    elif isinstance(good, float):
        out += [-good, good * 1e300, "0.05", np.float64(good)]
    elif isinstance(good, str):
        out += ["", "nope", good + "x", good.upper(), "\x00"]
    elif isinstance(good, Path):
        out += [good.with_name("missing"), good.parent, str(good) + "\x00", fx.a_file]
    elif isinstance(good, list | tuple):
        out += [
            [None] * len(good),
            list(good)[:-1],
            [*good, good[-1] if good else 0],
            [NAN] * max(len(good), 1),
            "abc",
        ]
    elif isinstance(good, dict):
        out += [{"x": 1}, {"limb1_p3": NAN}, {5: 1.0}, [("a", 1)]]
    else:
        out += [fx.mech if not isinstance(good, pkmtol.Mechanism) else fx.pset, "robots/r2rps_ups"]
    return out


# --- running ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Case:
    """One call: ``target`` with the argument ``slot`` (an index or a keyword) replaced by ``value``."""

    target: Target
    slot: int | str
    value_index: int
    draw: int = -1  # ≥ 0: a random value drawn with this seed (:func:`random_value`) instead


def value_of(case: Case, good: Any, fx: Fixtures) -> Any:
    """The bad value of ``case`` for the good value ``good``."""
    if case.draw >= 0:
        return random_value(good, np.random.default_rng(case.draw))
    return bad_values(good, fx)[case.value_index]


def random_value(good: Any, rng: np.random.Generator) -> Any:
    """A random bad value shaped like ``good``: magnitudes from 1e-320 to 1e308, one entry broken, any shape.

    Whole numbers stay within ±10⁶ (a valid but huge count is no bug, only slow).
    """
    x = float(rng.choice([-1.0, 1.0]) * 10.0 ** rng.uniform(-320, 308))
    kind = int(rng.integers(5))
    if isinstance(good, np.ndarray) and good.dtype.kind in "fi" and good.size:
        arr = good.astype(float).copy()
        if kind == 0:
            arr.flat[int(rng.integers(arr.size))] = rng.choice([NAN, INF, -INF, x])
        elif kind == 1:
            arr = arr * x
        elif kind == 2:
            arr = rng.standard_normal(tuple(int(n) for n in rng.integers(0, 6, size=int(rng.integers(0, 4)))))
        elif kind == 3:
            arr = np.round(arr * 10.0 ** rng.integers(-3, 4)).astype(int)
        else:
            arr = arr + rng.standard_normal(arr.shape) * 10.0 ** rng.uniform(-12, 3)
        return arr
    if isinstance(good, bool | int):
        return int(rng.integers(-(10**6), 10**6)) if kind < 3 else x
    if isinstance(good, float):
        return good * x if kind < 2 else x
    if isinstance(good, str):
        return "".join(chr(int(c)) for c in rng.integers(1, 0x2FF, size=int(rng.integers(0, 12))))
    if isinstance(good, list | tuple) and good:
        return [random_value(g, rng) for g in good][: int(rng.integers(0, len(good) + 2))]
    return x


@dataclass
class Report:
    """What a fuzzing run found.

    Attributes:
        calls: Calls made.
        outcomes: Count per outcome (``ok``, a PkmtolError class name, ``BUG``).
        bugs: Per escape place (``Type at file:line``): the cases that reached it.
        targets: The callables covered (with at least one case).
        slow: Calls that took longer than :data:`HANG_S`.
        seconds: Wall time.
    """

    calls: int = 0
    outcomes: Counter = field(default_factory=Counter)
    bugs: dict[str, list[str]] = field(default_factory=dict)
    targets: set[str] = field(default_factory=set)
    slow: list[str] = field(default_factory=list)
    seconds: float = 0.0

    @property
    def escapes(self) -> int:
        return self.outcomes["BUG"]


def slots(args: list[Any], kwargs: dict[str, Any]) -> list[int | str]:
    return [*range(len(args)), *kwargs]


def cases(fx: Fixtures, seed: int, light: bool = False, draws: int = 0) -> Iterator[Case]:
    """Every (target, argument, bad value) in a seeded order; ``light``: heavy targets' type errors only.

    ``draws``: per argument, that many random values more (:func:`random_value`, seeded by ``seed``).
    """
    out: list[Case] = []
    counter = 0
    for target in TARGETS:
        _, args, kwargs = target.build(fx)
        for slot in slots(args, kwargs):
            good = args[slot] if isinstance(slot, int) else kwargs[slot]
            n = len(bad_values(good, fx))
            for i in range(n):
                if light and target.heavy and i not in _TYPE_ERRORS:
                    continue
                out.append(Case(target, slot, i))
            for _ in range(0 if light and target.heavy else draws):
                counter += 1
                out.append(Case(target, slot, -1, draw=seed * 1_000_003 + counter))
    random.Random(seed).shuffle(out)
    yield from out


#: Indices into :data:`GENERIC` of values no function accepts as an argument of a design.
_TYPE_ERRORS = (1, 2, 11, 16, 17)


def describe(case: Case, value: Any) -> str:
    text = repr(value)
    if len(text) > 60:
        text = text[:57] + "..."
    return f"{case.target.name}[{case.slot}]={text}"


def _place(err: BaseException) -> str:
    frames = traceback.extract_tb(err.__traceback__)
    inside = [fr for fr in frames if "/pkmtol/" in fr.filename] or frames
    fr = inside[-1]
    where = fr.filename.split("/src/")[-1] if "/src/" in fr.filename else fr.filename.rsplit("/", 1)[-1]
    return f"{type(err).__name__} at {where}:{fr.lineno}"


class _Hang(Exception):
    pass


def _alarm(signum: int, frame: Any) -> None:
    raise _Hang


def run_case(case: Case, fx: Fixtures) -> tuple[str, str | None, float]:
    """Run one case: (outcome, escape place or None, seconds)."""
    fn, args, kwargs = case.target.build(fx)
    good = args[case.slot] if isinstance(case.slot, int) else kwargs[case.slot]
    value = value_of(case, good, fx)
    if isinstance(case.slot, int):
        args[case.slot] = value
    else:
        kwargs[case.slot] = value
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, HANG_S)
    start = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            with np.errstate(all="ignore"):
                fn(*args, **kwargs)
        outcome, place = "ok", None
    except _Hang:
        outcome, place = "HANG", None
    except PkmtolError as err:
        outcome, place = type(err).__name__, None
    except Exception as err:  # noqa: BLE001 (what the fuzzer is for)
        outcome, place = "BUG", _place(err)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
    return outcome, place, time.perf_counter() - start


def fuzz(
    fx: Fixtures,
    seed: int,
    limit: int | None = None,
    light: bool = False,
    budget_s: float | None = None,
    draws: int = 0,
) -> Report:
    """Run up to ``limit`` cases (all by default) in the seeded order, within ``budget_s`` seconds."""
    rep = Report()
    start = time.perf_counter()
    here = os.getcwd()
    os.chdir(fx.tmp)  # a relative path given as a bad value lands in the fixtures' folder
    try:
        _fuzz(fx, seed, limit, light, budget_s, rep, start, draws)
    finally:
        os.chdir(here)
    rep.seconds = time.perf_counter() - start
    return rep


def _fuzz(
    fx: Fixtures,
    seed: int,
    limit: int | None,
    light: bool,
    budget_s: float | None,
    rep: Report,
    start: float,
    draws: int,
) -> None:
    for case in cases(fx, seed, light, draws):
        if limit is not None and rep.calls >= limit:
            break
        if budget_s is not None and time.perf_counter() - start > budget_s:
            break
        outcome, place, seconds = run_case(case, fx)
        rep.calls += 1
        rep.targets.add(case.target.name)
        rep.outcomes[outcome] += 1
        if place is not None:
            fn, args, kwargs = case.target.build(fx)
            good = args[case.slot] if isinstance(case.slot, int) else kwargs[case.slot]
            rep.bugs.setdefault(place, []).append(describe(case, value_of(case, good, fx)))
        if outcome == "HANG" or seconds > HANG_S:
            rep.slow.append(f"{case.target.name}[{case.slot}] value {case.value_index}: {seconds:.1f} s")


def callables_in_api() -> set[str]:
    """Every function of ``pkmtol.__all__`` and public method of its public classes (not exceptions)."""
    names: set[str] = set()
    for name in pkmtol.__all__:
        obj = getattr(pkmtol, name)
        if inspect.isclass(obj) and issubclass(obj, BaseException | Warning):
            continue
        if not inspect.isclass(obj):
            names.add(name)
            continue
        for member, value in inspect.getmembers(obj):
            if member.startswith("_") or isinstance(
                inspect.getattr_static(obj, member), property | cached_property
            ):
                continue
            if callable(value) and not inspect.isclass(value):
                names.add(f"{name}.{member}")
    return names


def check_good_calls(fx: Fixtures) -> dict[str, str]:
    """The targets whose good call fails (the table is wrong there), with the error."""
    bad: dict[str, str] = {}
    for target in TARGETS:
        try:
            fn, args, kwargs = target.build(fx)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                fn(*args, **kwargs)
        except Exception as err:  # noqa: BLE001
            bad[target.name] = f"{type(err).__name__}: {str(err)[:300]}"
    return bad
