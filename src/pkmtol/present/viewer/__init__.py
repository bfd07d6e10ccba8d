"""The 3D viewer: a design in meshcat (the paper's Figs. 7 and 9 in one scene).

Modules: :mod:`~pkmtol.present.viewer.scene` (``build_scene``), :mod:`~pkmtol.present.viewer.layers`,
:mod:`~pkmtol.present.viewer.legend`, :mod:`~pkmtol.present.viewer.geometry`,
:mod:`~pkmtol.present.viewer.options`, :mod:`~pkmtol.present.viewer.colours`,
:mod:`~pkmtol.present.viewer.server` (loopback meshcat server), :mod:`~pkmtol.present.viewer.browser`
(headless Chromium), :mod:`~pkmtol.present.viewer.export` (``export_html``, ``show``).


:func:`build_scene` draws a :class:`~pkmtol.design.job.DesignResult` into a ``meshcat.Visualizer``;
:func:`export_html` writes it as one self-contained HTML page; :func:`show` serves it live.
They return what they drew as frozen dataclasses: :class:`SceneSummary` (with a
:class:`SpheresLayer` and a :class:`VerificationLayer` when those layers are drawn) and
:class:`HtmlExport`.
Every layer has its own meshcat path (under ``/meshcat``) so it can be hidden from the viewer's
"Open Controls" panel:

``pkmtol/robot/<limb>``
    Each limb's URDF visuals through Pinocchio's ``MeshcatVisualizer`` (one visualizer per limb,
    all sharing one ``meshcat.Visualizer``), posed at the most error-sensitive pose (the design
    point, ``result.grid.poses[result.worst_index]``). A limb without visuals (built from a bare
    ``pin.Model``) is drawn as a skeleton: a ball at every joint, a rod between joints. A
    key-framed animation (paused; play it from the controls' "Animations" folder) moves the whole
    mechanism through every task-space grid point, starting at the design point.
``pkmtol/error_spheres/<k>``
    One sphere per task-space grid point ``k`` (the paper's Fig. 7), centred at the grid point,
    **radius = scale · σ[Δλ_k]** where σ[Δλ_k] is the standard deviation of the accuracy index at
    that point. By default (``sigma="search"``) it is the paper's sensitive-pose-search quantity:
    every uncompensatable error ``η_c ~ N(0, 1)`` (1 m or 1 rad), so σ is in metres per unit error
    and the largest sphere is the design point; with ``sigma="design"`` the errors are
    ``N(0, σ_i²)`` at the verified design's tolerances (and the tracker noise after a
    calibration) and σ is in metres; both from the compensation mode's maps (``result.maps``).
    ``scale`` makes the largest sphere ``max_sphere_radius_m`` (default: 0.2 × the smallest
    distance between two grid points, so that spheres never touch and the mechanism shows between
    them; opacity 0.35); it is returned (``SceneSummary.spheres``, a :class:`SpheresLayer`:
    ``radius_per_sigma``), written in the legend and set as the property
    ``pkmtol_radius_per_sigma`` of the layer node. Colour: viridis over [min σ, max σ] (dark
    purple = least, yellow = most sensitive). With ``glyph="ellipsoid"`` each is the 1σ ellipsoid
    of P's error (the covariance ``L Σ Lᵀ`` at the point), so that the error's direction shows.
``pkmtol/verification/...``
    The Monte Carlo verification (the paper's Fig. 9). ``cloud/safe`` and ``cloud/failed``:
    position-error vectors ``Δp = L η_c (+ N ν)`` of P at the design point for ``cloud_samples`` draws of
    η_c from the verification distribution (default Gaussian) at the verified tolerances,
    magnified by ``cloud_radius_m / Δλ*`` and drawn around the transparent ``cloud/target`` sphere
    of radius ``cloud_radius_m`` (= Δλ*, magnified): a point is green when ``‖Δp‖ ≤ Δλ*`` and
    red otherwise. The cloud is centred just outside the task space, radially out from the
    design point (a thin rod joins the two), so that it does not hide the mechanism.
    ``task_space/safe`` and ``task_space/failed``: every sample of the actual verification run
    (``result.verification[distribution]``, random poses over the task space) at its task-space
    point, red if its Δλ > Δλ* (the green ones are hidden at first: thousands of dots would
    hide the spheres; tick ``visible`` in the controls, or set ``show_safe_samples``).
``pkmtol/reference``
    ``P``: the reference point (magenta ball) at the design pose; ``platform_frame``: a triad
    (x red, y green, z blue) at the platform frame O'; ``offset``: the rod O'→P.
``pkmtol/ground``
    A line grid just below the base, over the footprint of the mechanism and the task space.
``pkmtol/legend``
    A panel with the scales and the colour bar (also overlaid on the exported HTML page).

The camera frames the mechanism (design pose) and the task-space grid by their bounding box: the
``pkmtol`` node is shifted so that the box's centre is at meshcat's origin, which its orbit controls
look at (``SceneSummary.offset_m``), and meshcat's own grid and axes there are hidden.

The meshcat server started here (:class:`MeshcatServer`) listens on 127.0.0.1 only — meshcat's
own ``meshcat.Visualizer()`` server binds its HTTP port on every interface — and is stopped
(killed and reaped) when the export ends, the ``with`` block exits, or the Python process exits;
it also exits by itself if its parent process dies.
"""
