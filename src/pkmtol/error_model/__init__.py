"""Stage 3, the error model: parameters, error twists, wrenches and the compensatable/uncompensatable split.

Modules: :mod:`~pkmtol.error_model.parameters` (the ``urdf`` and ``dh`` sets),
:mod:`~pkmtol.error_model.twists` (error columns at a pose), :mod:`~pkmtol.error_model.separation`
(Eqs. 5–8, 25 at one pose), :mod:`~pkmtol.error_model.sweep` (over many poses, classes),
:mod:`~pkmtol.error_model.table` (``pkmtol errors``).
"""
