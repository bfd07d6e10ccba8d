"""Stage 2, closed-chain kinematics: inverse and forward solves of nominal and perturbed mechanisms.

Modules: :mod:`~pkmtol.kinematics.closed_chain` (Newton on the closure equations),
:mod:`~pkmtol.kinematics.perturbation` (limb models with geometric errors),
:mod:`~pkmtol.kinematics.check` (``pkmtol check``: mobility, constraints, reachability).
"""
