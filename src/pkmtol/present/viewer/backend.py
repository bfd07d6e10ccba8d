"""The meshcat import, guarded: the 3D viewer's one dependency that may be missing."""

from __future__ import annotations

from typing import Any

from pkmtol.exceptions import ViewerError


def require_meshcat() -> Any:
    """Import meshcat or raise :class:`ViewerError` with what to do."""
    try:
        import meshcat
        import meshcat.geometry  # noqa: F401
        import meshcat.transformations  # noqa: F401
    except ImportError as err:  # pragma: no cover - meshcat is a dependency
        raise ViewerError(
            f"the 3D viewer needs meshcat ({err}); install it with `pip install meshcat` "
            "(it is a dependency of pkmtol: `pip install pkmtol` brings it)"
        ) from err
    return meshcat
