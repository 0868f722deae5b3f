"""``scripts/steadied_keypoints.py``: a view's swapped wrists are put back with their confidences, and a one-frame
jump of a detection is steadied by the median over the frames around it."""

from __future__ import annotations

import numpy as np

from swarmpose.camera import Camera
from swarmpose.joints import JOINTS15
from swarmpose.triangulation import reproject


def test_swapped_wrists_are_put_back_and_a_jump_is_steadied(load_script):
    m = load_script("steadied_keypoints")
    rng = np.random.default_rng(0)
    cams = [Camera.look_at(f"c{i}", [3000 * np.cos(a), 3000 * np.sin(a), 1500], [0, 0, 1000])
            for i, a in enumerate((0.2, 1.7, 3.2, 4.6))]
    T = 9
    joints = rng.normal(0, 300, (15, 3)) + [0, 0, 1000] + np.linspace(0, 80, T)[:, None, None]  # (T, 15, 3)
    truth = reproject(cams, joints)  # (T, C, 15, 2)
    conf = rng.uniform(0.5, 1.0, truth.shape[:-1])
    lw, rw = JOINTS15.index("l_wrist"), JOINTS15.index("r_wrist")
    kp, cf = truth.copy(), conf.copy()
    kp[4, 2, [lw, rw]] = truth[4, 2, [rw, lw]]  # view 2, frame 4: the wrists' labels exchanged
    cf[4, 2, [lw, rw]] = conf[4, 2, [rw, lw]]
    out, out_conf = m.relabelled(cams, kp, cf, 0.05, 20.0)
    np.testing.assert_allclose(out, truth)
    np.testing.assert_array_equal(out_conf, conf)  # the confidences went back with their detections
    jumped = truth.copy()
    jumped[4, 1, lw] += [60.0, -40.0]  # one frame's detection 72 px off
    steady = m.steadied(jumped, conf, 2, 0.05)
    assert np.linalg.norm(steady[4, 1, lw] - truth[4, 1, lw]) < 5  # the median of its neighbours' (a slow motion)
    # elsewhere within a frame's motion (3-4 px here) of the truth, a full window's exactly on it
    assert np.linalg.norm(steady - truth, axis=-1).max() < 8
    np.testing.assert_allclose(steady[2:7, [0, 2, 3]], truth[2:7, [0, 2, 3]])
    errs = m.errors(jumped, conf, truth)
    assert errs["wrists"]["over_50px"] > 0 and m.errors(steady, conf, truth)["wrists"]["over_50px"] == 0
