"""Stage 6, presentation: tables and files (:mod:`~pkmtol.present.tables`), figures, the 3D viewer."""
