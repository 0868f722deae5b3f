"""HumanEva-I and HumanEva-II as distributed: calibration, sync offsets, mocap ground truth, video, backgrounds.

Everything here follows ``shared/reference/humaneva-facts.md`` (sections 1-6), which paraphrases the
HumanEva support code v1.1 (Sigal, Brown 2006-2007). MATLAB indices in that code are 1-based; the
synchronized frame numbers ``F`` used below (and in the official partitions) are 1-based too.

Layout (paths relative to the release root; ``<CAM>`` is ``C1..C3``/``BW1..BW4`` for HumanEva-I,
``C1..C4`` for HumanEva-II)::

    <S>/Calibration_Data/<CAM>.cal              22 numbers: fc(2) cc(2) alpha_c kc(5) R(9, row-major) T(3, mm)
    <S>/Sync_Data/<Action>_<Trial>_(<CAM>).ofs   3 numbers: im_st mc_st mc_sc
    <S>/Image_Data/<Action>_<Trial>_(<CAM>).avi  video (or a folder <Action>_<Trial>_(<CAM>)/ of numbered images)
    <S>/Mocap_Data/<Action>_<Trial>.c3d          Vicon C3D (the support code caches it as .mat beside it)
    <S>/Mocap_Data/Static.c3d                    static trial (torso radius for the pose modifiers)
    <S>/Mocap_Data/<S>.mp                        Vicon subject measurements ("$Name = value" lines)
    Background/Background_*_(<CAM>).avi          HumanEva-I background footage (release root)
    <S>/Background/Background_*_(<CAM>)/         HumanEva-II background footage (image folders)

Modules: :mod:`~swarmpose.datasets.humaneva.layout` (cameras, rates, partitions, file paths),
:mod:`~swarmpose.datasets.humaneva.files` (reading numbers and ``.mat`` files),
:mod:`~swarmpose.datasets.humaneva.calibration` (``.cal``, ``.ofs``, ``.mp``),
:mod:`~swarmpose.datasets.humaneva.mocap` (mocap and ground truth),
:mod:`~swarmpose.datasets.humaneva.video` (video, background model, silhouettes) and
:mod:`~swarmpose.datasets.humaneva.sequence` (a trial as a sequence). Every name below is importable
from this package.

Public API
----------
Parsers (each raises :class:`~swarmpose.errors.DataError` for a missing/unreadable file and
:class:`~swarmpose.errors.FormatError` naming the file and the line or field for a malformed one):
:func:`parse_calibration` / :func:`read_calibration` (``.cal`` -> :class:`~swarmpose.camera.Camera`),
:func:`read_offsets` (``.ofs``), :func:`read_mp` (``.mp``), :func:`read_mocap` (``.mat`` cache or
``.c3d``), :func:`read_background_mat` (the support code's ``Background_(<CAM>).mat``).

Synchronisation: :func:`synchronize` (the ``sync_stream`` rule, facts section 2).
Ground truth: :func:`humaneva_ground_truth` (the ``cur_frame`` rule, facts section 4.2) and
:func:`joints15_from_points20`. Background model: :func:`humaneva_background_model`,
:func:`humaneva_silhouette` (facts section 6). Video: :class:`VideoSource` (OpenCV's
``cv2.VideoCapture``, with ``imageio`` as fallback; or a folder of numbered images).
Sequences: :class:`HumanEvaTrial`, :func:`open_humaneva`, :func:`humaneva_sequence` (a lazily read
:class:`~swarmpose.io.sequence.MultiViewSequence`), :func:`parse_humaneva_spec`.

Choices where the sources are ambiguous or where the support code would crash (each is tested):

* **Double joints.** ``JOINTS15`` ground truth stores one point per joint. For thorax, elbows and
  knees HumanEva's ``error.m`` averages the *distances* of two points (torsoProximal/headProximal,
  upperArmDistal/lowerArmProximal, upperLegDistal/lowerLegProximal); we store the *midpoint* of the
  two (as VideoPose3D does). The two points differ by a few mm at the elbows (arm pose modifier)
  and thorax, so errors against the midpoint differ from ``error.m`` by at most half that gap. The
  full 20 points are kept in :attr:`GroundTruth.points20` for an exact ``error.m`` evaluation.
* **Invalid frames.** A frame is valid when the 39 Plug-in-Gait markers are non-zero in both
  bracketing mocap frames (as ``cur_frame``). Stricter than the support code, a frame is also
  invalid when a virtual marker it uses is (0, 0, 0) or its segment axes are not orthogonal to 1e-4
  (the support code substitutes an identity frame or stops with an error). Invalid frames are NaN
  rows in the ground truth and are skipped by HumanEva's evaluation.
* **Segment axes** come from the labels following each ``...O`` label: +1 = z point, +2 = x point,
  +3 = y point (index offsets, as the support code). Orientations are interpolated by slerp,
  positions linearly, between mocap frames ``floor(p)`` and ``floor(p) + 1``; at an integer ``p``
  only frame ``p`` is used (the support code would index past the end at the last frame).
* **Marker labels** are found by substring match (MATLAB ``findstr``), first match; ``LABELS``,
  ``LABELS2``, ... are concatenated (C3D convention for more than 255 markers).
* **Torso radius** for the pelvis tilt is computed from ``Static`` markers (as the support code,
  whose loader overwrites ``Markers`` with the static trial's); without a static trial, from the
  trial itself (recorded in the provenance).
* **.cal rotation**: the files are written with 6 decimals, so ``R`` is orthonormal only to ~1e-6;
  it is projected onto the nearest rotation (SVD) when within 1e-3, rejected otherwise. Exactly 22
  numbers are required (a 25-number file is the PARSEC bodytrack variant).
* **Images** of the sequence are grey ``(C, H, W)`` uint8 (``cv2`` RGB->grey); the colour frames are
  available through :meth:`HumanEvaFrames.colour` and feed the ``silhouette`` stream, which applies
  HumanEva's per-pixel Gaussian background mixture on colour values scaled to [0, 1].
* **Default partition**: ``split="auto"`` picks the official Validate frames for trial 1, Test for
  trial 2, Train for trial 3 (and HumanEva-II's test ranges); ``split="all"`` is every synchronized
  frame from 6 on (HumanEva-I, skipping the XVID duplicates) or from 1 (HumanEva-II).
* **Background footage** is summarised from at most ``background_frames`` evenly spaced frames per
  recording session (default 100; ``None`` = every frame, as the support code) and cached as
  ``.npz`` under ``cache_dir`` (default ``cache/humaneva``, relative to the working directory).
"""

from __future__ import annotations

from swarmpose.datasets.humaneva.calibration import (
    CAL_FIELDS,
    MP_NAMES,
    OFS_FIELDS,
    CalibrationValues,
    StreamOffset,
    SyncInfo,
    matlab_round,
    mp_value,
    parse_calibration,
    read_calibration,
    read_mp,
    read_offsets,
    synchronize,
)
from swarmpose.datasets.humaneva.layout import (
    DATASET_CAMERAS,
    DEFAULT_CAMERAS,
    DEFAULT_RISK,
    FIRST_FRAME_I,
    FRAME_RANGES,
    HUMANEVA_I_CAMERAS,
    HUMANEVA_II_CAMERAS,
    IMAGE_EXTENSIONS,
    MOCAP_RATE,
    OFS_UPDATE_SANITY,
    VIDEO_RATE,
    detect_dataset,
    humaneva_frame_range,
    trial_files,
)
from swarmpose.datasets.humaneva.mocap import (
    BODY_POSE20,
    HEAD_LENGTH_MM,
    JOINT_LABELS,
    JOINTS15_FROM_20,
    PELVIS_SHIFT_MM,
    SEGMENT_GROUPS,
    VALIDITY_MARKERS,
    GroundTruth,
    MocapMarkers,
    humaneva_ground_truth,
    joints15_from_points20,
    limb_lengths,
    limb_parameters,
    read_c3d,
    read_mocap,
    read_mocap_mat,
    subject_measurements,
)
from swarmpose.datasets.humaneva.sequence import (
    HumanEvaSpec,
    HumanEvaTrial,
    humaneva_sequence,
    open_humaneva,
    parse_humaneva_spec,
)
from swarmpose.datasets.humaneva.video import (
    BackgroundModel,
    HumanEvaFrames,
    VideoSource,
    humaneva_background_model,
    humaneva_silhouette,
    load_background_model,
    read_background_mat,
)

__all__ = [
    "VIDEO_RATE",
    "MOCAP_RATE",
    "HEAD_LENGTH_MM",
    "HUMANEVA_I_CAMERAS",
    "HUMANEVA_II_CAMERAS",
    "BODY_POSE20",
    "VALIDITY_MARKERS",
    "FRAME_RANGES",
    "CalibrationValues",
    "StreamOffset",
    "SyncInfo",
    "MocapMarkers",
    "GroundTruth",
    "BackgroundModel",
    "VideoSource",
    "HumanEvaFrames",
    "HumanEvaTrial",
    "HumanEvaSpec",
    "parse_calibration",
    "read_calibration",
    "read_offsets",
    "read_mp",
    "mp_value",
    "read_mocap",
    "read_mocap_mat",
    "read_c3d",
    "synchronize",
    "matlab_round",
    "limb_lengths",
    "limb_parameters",
    "subject_measurements",
    "humaneva_ground_truth",
    "joints15_from_points20",
    "humaneva_background_model",
    "humaneva_silhouette",
    "read_background_mat",
    "load_background_model",
    "open_humaneva",
    "parse_humaneva_spec",
    "humaneva_sequence",
    "humaneva_frame_range",
    "detect_dataset",
    "trial_files",
    "CAL_FIELDS",
    "DATASET_CAMERAS",
    "DEFAULT_CAMERAS",
    "DEFAULT_RISK",
    "FIRST_FRAME_I",
    "IMAGE_EXTENSIONS",
    "JOINTS15_FROM_20",
    "JOINT_LABELS",
    "MP_NAMES",
    "OFS_FIELDS",
    "OFS_UPDATE_SANITY",
    "PELVIS_SHIFT_MM",
    "SEGMENT_GROUPS",
]
