"""Your own recordings: videos or image folders of calibrated cameras become a sequence folder.

See :func:`import_recording` (``swarmpose import``) and ``docs/recordings.md``.
"""

from __future__ import annotations

from swarmpose.datasets.recording.build import (
    IMPORT_DIR,
    SILHOUETTE_MODES,
    ImportOptions,
    RecordingImport,
    import_recording,
)

__all__ = ["ImportOptions", "RecordingImport", "import_recording", "SILHOUETTE_MODES", "IMPORT_DIR"]
