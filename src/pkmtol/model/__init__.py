"""Stage 1, the mechanism: limbs (URDF, ``pin.Model`` or a closed-loop tree), platform, P, task space.

Modules: :mod:`~pkmtol.model.limb` (one serial limb), :mod:`~pkmtol.model.mechanism` (the
mechanism and its checks), :mod:`~pkmtol.model.loader` (``mechanism.toml`` → mechanism),
:mod:`~pkmtol.model.reading` (TOML keys and URDF files, shared by both loaders),
:mod:`~pkmtol.model.taskspace`, :mod:`~pkmtol.model.dh` (D–H tables), the closed-loop import:
:mod:`~pkmtol.model.sidecar`, :mod:`~pkmtol.model.tree_cut`, :mod:`~pkmtol.model.closed_loop` (URDF
tree), :mod:`~pkmtol.model.mjcf` and :mod:`~pkmtol.model.mjcf_checks` (MJCF), and the way out:
:mod:`~pkmtol.model.constraints` (one ``pin.Model`` plus Pinocchio 4 constraint models).
"""
