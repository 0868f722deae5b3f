"""MediaPipe Pose (BlazePose): 33 body landmarks and a person mask in one image, on the CPU.

Install (the ``detect`` extra)::

    pip install 'swarmpose[detect]'

MediaPipe 0.10.14 declares jax, jaxlib, sounddevice and ``opencv-contrib-python`` as dependencies;
the last clashes with swarmpose's ``opencv-python-headless`` (both provide ``cv2``). Where that
matters, install it without its declared dependencies and add the few it really needs::

    pip install --no-deps 'mediapipe==0.10.14'
    pip install absl-py attrs flatbuffers 'protobuf>=4.25.3,<5'

Only 0.10.14 is supported: it ships the pose models inside the wheel (``pose_detection.tflite``
and ``pose_landmark_full.tflite``), so it runs offline; later versions download models at run time.
Even 0.10.14 ships only the "full" landmark model: ``model_complexity`` 0 (lite) and 2 (heavy) would
be downloaded into the installed package on first use, so they are refused here unless their file
is already there.

``MediaPipePose(model_complexity=1, min_detection_confidence=0.5, static_image_mode=False,
mask_threshold=0.5, *, min_tracking_confidence=0.5, smooth_landmarks=True, segmentation=True)``
is a :class:`~swarmpose.detection.base.PersonDetector`. In video mode (``static_image_mode=False``)
MediaPipe tracks the person from the previous frame, so feed one view's frames in order and call
:meth:`MediaPipePose.reset` before another view. A detection with ``roi`` runs a separate
still-image graph on the crop and leaves the video tracking state alone.

MediaPipe picks the most prominent person only; ``confidence`` is its per-landmark ``visibility``.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import numpy as np

from swarmpose.detection.base import LandmarkDetector, RawLandmarks
from swarmpose.detection.joints import BLAZEPOSE33
from swarmpose.errors import ConfigError

__all__ = ["MediaPipePose", "INSTALL_HINT", "import_mediapipe_pose"]

SUPPORTED_VERSION = "0.10.14"
INSTALL_HINT = (
    "MediaPipe is not installed: install swarmpose's detect extra with `pip install 'swarmpose[detect]'`, "
    "or, to keep opencv-python-headless and skip jax, `pip install --no-deps mediapipe==0.10.14` followed "
    "by `pip install absl-py attrs flatbuffers 'protobuf>=4.25.3,<5'`"
)
_LANDMARK_MODELS = {0: "pose_landmark_lite.tflite", 1: "pose_landmark_full.tflite", 2: "pose_landmark_heavy.tflite"}


def import_mediapipe_pose() -> tuple[Any, str]:
    """``(mediapipe.python.solutions.pose, mediapipe.__version__)``.

    Raises
    ------
    ConfigError
        MediaPipe is missing or broken; the message says how to install it.
    """
    try:
        import mediapipe
        from mediapipe.python.solutions import pose
    except ImportError as exc:
        raise ConfigError(f"{INSTALL_HINT} ({exc})") from None
    return pose, str(getattr(mediapipe, "__version__", "unknown"))


class MediaPipePose(LandmarkDetector):
    """MediaPipe Pose as a :class:`~swarmpose.detection.base.PersonDetector` (see the module docstring).

    Parameters
    ----------
    model_complexity : int
        0, 1 or 2; only 1 ships with MediaPipe 0.10.14 (the others are refused when absent).
    min_detection_confidence : float
        Person detector threshold, in ``[0, 1]``.
    static_image_mode : bool
        True: every image is detected from scratch (no tracking, no temporal smoothing).
    mask_threshold : float
        A pixel is the person where MediaPipe's segmentation probability is ``>=`` this.
    min_tracking_confidence, smooth_landmarks : float, bool
        MediaPipe's video-mode settings.
    segmentation : bool
        Whether to compute the mask (False: ``Detection.mask`` is None, slightly faster).

    Raises
    ------
    ConfigError
        MediaPipe is missing, a setting is out of range, or the chosen model file is absent.
    """

    name = "mediapipe-pose"
    keypoint_names = BLAZEPOSE33

    def __init__(self, model_complexity: int = 1, min_detection_confidence: float = 0.5,
                 static_image_mode: bool = False, mask_threshold: float = 0.5, *,
                 min_tracking_confidence: float = 0.5, smooth_landmarks: bool = True, segmentation: bool = True):
        if model_complexity not in _LANDMARK_MODELS:
            raise ConfigError(f"model_complexity must be 0, 1 or 2, got {model_complexity!r}")
        for label, value in (("min_detection_confidence", min_detection_confidence),
                             ("min_tracking_confidence", min_tracking_confidence),
                             ("mask_threshold", mask_threshold)):
            if not 0.0 <= float(value) <= 1.0:
                raise ConfigError(f"{label} must be in [0, 1], got {value!r}")
        self._pose_module, self.version = import_mediapipe_pose()
        model = Path(self._pose_module.__file__).parents[2] / "modules" / "pose_landmark"
        model = model / _LANDMARK_MODELS[model_complexity]
        if not model.is_file():
            raise ConfigError(f"MediaPipe {self.version} has no {model.name} (model_complexity="
                              f"{model_complexity}) and would download it; use model_complexity=1, whose "
                              "model ships with mediapipe==0.10.14")
        self.model_complexity = int(model_complexity)
        self.min_detection_confidence = float(min_detection_confidence)
        self.min_tracking_confidence = float(min_tracking_confidence)
        self.static_image_mode = bool(static_image_mode)
        self.mask_threshold = float(mask_threshold)
        self.smooth_landmarks = bool(smooth_landmarks)
        self.segmentation = bool(segmentation)
        self._graphs: dict[bool, Any] = {}  # static -> mediapipe Pose, made on first use

    @property
    def settings(self) -> dict[str, Any]:
        return {"model_complexity": self.model_complexity, "min_detection_confidence": self.min_detection_confidence,
                "min_tracking_confidence": self.min_tracking_confidence, "static_image_mode": self.static_image_mode,
                "smooth_landmarks": self.smooth_landmarks, "segmentation": self.segmentation,
                "mask_threshold": self.mask_threshold}

    def _graph(self, static: bool) -> Any:
        static = static or self.static_image_mode
        if static not in self._graphs:
            self._graphs[static] = self._pose_module.Pose(
                static_image_mode=static, model_complexity=self.model_complexity,
                smooth_landmarks=self.smooth_landmarks, enable_segmentation=self.segmentation,
                min_detection_confidence=self.min_detection_confidence,
                min_tracking_confidence=self.min_tracking_confidence)
        return self._graphs[static]

    def _infer(self, rgb: np.ndarray, *, static: bool) -> RawLandmarks | None:
        graph = self._graph(static)
        with warnings.catch_warnings():  # protobuf 4's "SymbolDatabase.GetPrototype() is deprecated"
            warnings.filterwarnings("ignore", message=r"SymbolDatabase\.GetPrototype", category=UserWarning)
            result = graph.process(rgb)
        if result.pose_landmarks is None:
            return None
        marks = result.pose_landmarks.landmark
        xy = np.array([(m.x, m.y) for m in marks], dtype=np.float64)
        visibility = np.array([m.visibility for m in marks], dtype=np.float64)
        mask = None if result.segmentation_mask is None else np.asarray(result.segmentation_mask)
        return RawLandmarks(xy, visibility, mask)

    def reset(self) -> None:
        """Forget the video tracking state (call before another view or video)."""
        graph = self._graphs.get(False)
        if graph is not None:
            graph.reset()

    def close(self) -> None:
        """Free MediaPipe's graphs (they are made again on the next detection)."""
        graphs, self._graphs = self._graphs, {}
        for graph in graphs.values():
            graph.close()

    def __enter__(self) -> MediaPipePose:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
