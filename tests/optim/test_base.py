"""The ask/tell contract: protocol guards, the score rule, the loop."""

from __future__ import annotations

import numpy as np
import pytest

from swarmpose.errors import ShapeError
from swarmpose.optim import ConstrictedPSO, optimize
from swarmpose.optim.base import check_scores, feasibility
from swarmpose.optim.testfunctions import sphere


def _pso(seed: int = 0, **kw) -> ConstrictedPSO:
    return ConstrictedPSO(np.ones(3), np.ones(3), 5, 4, np.random.default_rng(seed), **kw)


def test_smoke_ask_shape_and_dtype():
    x = _pso().ask()
    assert x.shape == (5, 3) and x.dtype == np.float64


def test_exception_tell_without_ask():
    with pytest.raises(RuntimeError, match="without a preceding ask"):
        _pso().tell(np.zeros(5))


def test_exception_double_tell_and_double_ask():
    opt = _pso()
    opt.ask()
    with pytest.raises(RuntimeError, match="twice"):
        opt.ask()
    opt.tell(np.zeros(5))
    with pytest.raises(RuntimeError):
        opt.tell(np.zeros(5))


def test_exception_bad_score_shape_names_both_shapes():
    opt = _pso()
    opt.ask()
    with pytest.raises(ShapeError, match=r"\(5,\).*\(4,\)"):
        opt.tell(np.zeros(4))
    with pytest.raises(ValueError):  # ShapeError is a ValueError
        opt.tell(np.zeros((5, 1)))
    opt.tell(np.zeros(5))  # the failed tells did not consume the ask


def test_exception_ask_after_done():
    opt = _pso()
    optimize(opt, sphere)
    assert opt.done
    with pytest.raises(RuntimeError, match="done"):
        opt.ask()


def test_best_before_tell_raises():
    with pytest.raises(RuntimeError):
        _ = _pso().best


def test_score_rule_nan_is_invalid_and_plus_inf_rejected():
    s = check_scores([1.0, np.nan, -np.inf], 3)
    assert s[0] == 1.0 and s[1] == -np.inf and s[2] == -np.inf
    with pytest.raises(ValueError, match=r"\+inf"):
        check_scores([0.0, np.inf], 2)


def test_nan_scores_never_become_best():
    opt = _pso()
    x = opt.ask()
    scores = -np.sum(x**2, axis=1)
    i_best = int(np.argmax(scores))
    scores[i_best] = np.nan
    opt.tell(scores)
    assert not np.allclose(opt.best.x, x[i_best])
    assert np.isfinite(opt.best.score)


def test_optimize_counts_evaluations_and_iterations():
    seen = []
    res = optimize(_pso(), sphere, callback=lambda o: seen.append(o.evaluations))
    assert res.evaluations == 20 and res.iterations == 4
    assert seen == [5, 10, 15, 20]
    assert res.score == pytest.approx(sphere(res.x[None])[0])


def test_feasibility_bounds_and_constraint_shape_check():
    x = np.array([[0.0, 0.0], [2.0, 0.0], [0.5, 0.5]])
    lo, hi = np.full(2, -1.0), np.full(2, 1.0)
    assert feasibility(x, lo, hi, None).tolist() == [True, False, True]
    ok = feasibility(x, lo, hi, lambda p: p[:, 1] < 0.2)
    assert ok.tolist() == [True, False, False]
    with pytest.raises(ShapeError):
        feasibility(x, lo, hi, lambda p: np.ones(7, bool))


def test_feasibility_equals_the_plain_bounds_test_and_asks_only_rows_inside():
    rng = np.random.default_rng(4)
    x = rng.uniform(-1.3, 1.3, (200, 5))
    x[7, 2] = np.nan  # NaN is never inside
    lo, hi = np.full(5, -1.0), np.array([1.0, 1.0, np.inf, 1.0, 1.0])
    inside = np.all((x >= lo) & (x <= hi), axis=1)
    assert feasibility(x, lo, hi, None).tolist() == inside.tolist()
    asked = []

    def constraint(p):
        asked.append(p.copy())
        return p[:, 0] > 0

    got = feasibility(x, lo, hi, constraint)
    assert got.tolist() == (inside & (x[:, 0] > 0)).tolist()
    assert len(asked) == 1 and np.array_equal(asked[0], x[inside])
    asked.clear()
    assert feasibility(x[inside], lo, hi, constraint).tolist() == (x[inside][:, 0] > 0).tolist()  # all inside
    assert np.array_equal(asked[0], x[inside])
    assert feasibility(np.full((3, 5), 5.0), lo, hi, constraint).tolist() == [False] * 3
    assert len(asked) == 1  # no row inside: the constraint is not asked


def test_rng_must_be_a_generator():
    with pytest.raises(TypeError, match="Generator"):
        ConstrictedPSO(np.ones(2), np.ones(2), 3, 3, 0)  # type: ignore[arg-type]


def test_a_staged_search_checks_its_scores_once_and_keeps_the_rule():
    """A staged search hands its stage's optimiser the scores it checked: the score rule and the protocol
    guards hold through it (NaN invalid, +inf and wrong shapes refused without using up the ask), and the stage
    counts the evaluations."""
    from swarmpose.optim import StagedPSO
    from swarmpose.optim.staged import Stage

    stages = [Stage("a", np.array([True, True, False]), np.ones(3), 3, 2), Stage("b", np.ones(3, bool), np.ones(3), 4, 2)]
    opt = StagedPSO(np.ones(3), np.ones(3), stages, np.random.default_rng(0))
    x = opt.ask()
    with pytest.raises(ValueError, match=r"\+inf"):
        opt.tell(np.array([0.0, np.inf, 1.0]))
    with pytest.raises(ShapeError):
        opt.tell(np.zeros(4))
    opt.tell(np.array([np.nan, -sphere(x[1:2])[0], -sphere(x[2:3])[0]]))
    assert opt.current.evaluations == 3 and opt.evaluations == 3
    assert opt.current.personal_best[1][0] == -np.inf
    with pytest.raises(RuntimeError, match="without a preceding ask"):  # the stage's own guards
        opt.current._tell_checked(np.zeros(3))
    opt.ask()
    with pytest.raises(RuntimeError, match="3 candidates asked, 2 scores told"):
        opt.current._tell_checked(np.zeros(2))
    opt.tell(np.zeros(3))
    result = optimize(opt, lambda p: -sphere(p))
    assert result.evaluations == 3 * 2 + 4 * 2 and opt.done
