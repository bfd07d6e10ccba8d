"""Stage 5, the design: tolerance allocation, reliability, verification, the main job.

Modules: :mod:`~pkmtol.design.job` (``allocate``, the main job), :mod:`~pkmtol.design.fosm` (the
paper's equal-effect FOSM tolerances), :mod:`~pkmtol.design.reliability` (exact R of the linear
model), :mod:`~pkmtol.design.exact` and :mod:`~pkmtol.design.cost` (designs beyond FOSM),
:mod:`~pkmtol.design.pose_search` (the most error-sensitive pose), :mod:`~pkmtol.design.verification`
(Monte Carlo, linear and exact).
"""
