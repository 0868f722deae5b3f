"""Person detection in the images: one person's 2D keypoints and segmentation mask per view and frame.

The interface is :mod:`swarmpose.detection.base` (``PersonDetector``, ``Detection``); the one detector
is MediaPipe Pose (:mod:`swarmpose.detection.mediapipe_pose`, an optional extra: ``pip install
'swarmpose[detect]'``; mediapipe itself is imported only when a ``MediaPipePose`` is made). Its 33
landmarks become the body model's 15 joints with :func:`swarmpose.detection.joints.to_joints15`, and
a view's video is detected once into a resumable cache by :mod:`swarmpose.detection.cache`.

This layer may import numpy, OpenCV, tqdm and swarmpose's errors, joints, camera and io only.
"""

from __future__ import annotations

from swarmpose.detection.base import (
    Detection,
    LandmarkDetector,
    PersonDetector,
    RawLandmarks,
    as_rgb,
    clip_roi,
)
from swarmpose.detection.cache import (
    VideoDetections,
    detect_video_file,
    detect_video_frames,
    iter_video_frames,
    load_detections,
    video_identity,
)
from swarmpose.detection.joints import BLAZEPOSE33, JOINT_SOURCES, SWAP15, SWAP33, to_joints15
from swarmpose.detection.mediapipe_pose import MediaPipePose

__all__ = ["Detection", "PersonDetector", "LandmarkDetector", "RawLandmarks", "as_rgb", "clip_roi",
           "VideoDetections", "detect_video_frames", "detect_video_file", "load_detections", "iter_video_frames",
           "video_identity", "BLAZEPOSE33", "JOINT_SOURCES", "SWAP15", "SWAP33", "to_joints15", "MediaPipePose"]
