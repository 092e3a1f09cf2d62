"""The joint placements memo shared by the estimators (`wbcbench.estimation._memo`): the placements of the
configuration asked for, bit for bit those of the forward kinematics, whatever was asked before."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from wbcbench.estimation._memo import memo_joint_placements, placement_memo
from wbcbench.side import Side
from wbcbench.tasks.placements import ForwardKinematics, joint_placements


def test_memo_gives_the_placements_of_the_configuration_asked_for(talos):
    model = talos.model
    fk = ForwardKinematics(model)
    memo = placement_memo(model, fk)
    assert placement_memo(model, ForwardKinematics(model)) is memo  # one per model and kinematic constants
    consts = (fk._kinds, fk._parents, fk._idx_q, fk._R0, fk._t0)
    qs = [pin.randomConfiguration(model, -np.ones(model.nq), np.ones(model.nq)) for _ in range(3)]
    qs.append(qs[0].copy())
    qs[3][10] = np.nextafter(qs[3][10], np.inf)  # one unit in the last place from configuration 0
    R, t = np.zeros_like(fk.R), np.zeros_like(fk.t)
    computed = 0
    for k in [0, 1, 0, 1, 2, 1, 2, 0, 3, 0, 3, 3]:
        q = qs[k]
        before = memo.q.copy()
        slot = memo_joint_placements(q, *consts, *memo.args, model.njoints)
        computed += not any(np.array_equal(row, q) and (np.signbit(row) == np.signbit(q)).all() for row in before)
        joint_placements(q, *consts, R, t)
        assert np.array_equal(memo.R[slot], R) and np.array_equal(memo.t[slot], t)
    assert computed == 5  # 0, 1, 2, 0 again (after 1 and 2), 3: one of the last two configurations is not recomputed


def test_a_configuration_changed_in_place_is_computed_again(talos):
    model = talos.model
    fk = ForwardKinematics(model)
    memo = placement_memo(model, fk)
    consts = (fk._kinds, fk._parents, fk._idx_q, fk._R0, fk._t0)
    q = pin.neutral(model)
    slot = memo_joint_placements(q, *consts, *memo.args, model.njoints)
    t_before = memo.t[slot].copy()
    q[0] += 0.5  # the base moved: same array, other content
    slot = memo_joint_placements(q, *consts, *memo.args, model.njoints)
    np.testing.assert_allclose(memo.t[slot][1:] - t_before[1:], [[0.5, 0.0, 0.0]] * (model.njoints - 1), atol=1e-12)


def test_the_kernels_views_of_the_memo_buffers_are_its_arrays(talos):
    """`memo_arrays` (inside a kernel, views made by `jit.c_view`) gives the memo's and the model's arrays: their
    shapes, strides and values, in the buffers' memory."""
    from wbcbench.estimation._memo import memo_arrays

    model = talos.model
    fk = ForwardKinematics(model)
    memo = placement_memo(model, fk)
    memo_joint_placements(pin.neutral(model), fk._kinds, fk._parents, fk._idx_q, fk._R0, fk._t0, *memo.args,
                          model.njoints)
    got = memo_arrays(memo.ints, memo.floats)
    expected = (fk._kinds, fk._parents, fk._idx_q, fk._R0, fk._t0, memo.q, memo.R, memo.t, memo.state, memo.work)
    for a, b in zip(got, expected):
        assert a.shape == b.shape and a.strides == b.strides and a.flags.c_contiguous
        assert np.array_equal(a, b, equal_nan=True)  # a slot not filled yet holds NaN
    for a in got[:3] + got[8:9]:
        assert np.shares_memory(a, memo.ints)
    for a in got[3:8] + got[9:]:
        assert np.shares_memory(a, memo.floats)


def test_a_slot_places_the_joints_asked_for_and_the_rest_when_asked(talos):
    """Asked for a prefix of the joints (a leg's), a slot places those; asked again for all, it places the rest:
    bit for bit the placements of one pass, and a configuration asked for again with fewer joints is not computed
    again."""
    from wbcbench.estimation._memo import joints_placing

    model = talos.model
    fk = ForwardKinematics(model)
    memo = placement_memo(model, fk)
    consts = (fk._kinds, fk._parents, fk._idx_q, fk._R0, fk._t0)
    sole = fk.frame_arrays([talos.sole_frame_id(s) for s in Side])[0]
    upto = joints_placing(sole)
    assert 1 < upto < model.njoints and upto == sole.max() + 1
    q = pin.randomConfiguration(model, -np.ones(model.nq), np.ones(model.nq))
    R, t = np.zeros_like(fk.R), np.zeros_like(fk.t)
    joint_placements(q, *consts, R, t)
    slot = memo_joint_placements(q, *consts, *memo.args, upto)
    assert memo.state[1 + slot] == upto
    assert np.array_equal(memo.R[slot, :upto], R[:upto]) and np.array_equal(memo.t[slot, :upto], t[:upto])
    memo.R[slot, upto:] = np.nan  # not placed yet: must be computed, not read
    assert memo_joint_placements(q, *consts, *memo.args, model.njoints) == slot
    assert memo.state[1 + slot] == model.njoints
    assert np.array_equal(memo.R[slot], R) and np.array_equal(memo.t[slot], t)
    memo.R[slot, 0, 0, 0] = 7.0  # a marker: a hit asking for fewer joints reads the slot as it is
    assert memo_joint_placements(q, *consts, *memo.args, upto) == slot and memo.R[slot, 0, 0, 0] == 7.0
    memo.R[slot, 0] = np.eye(3)
