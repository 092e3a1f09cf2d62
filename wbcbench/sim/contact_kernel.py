"""Ground-truth contact wrenches on the soles in one compiled call (see :mod:`wbcbench.jit`).

MuJoCo stores each contact's force as constraint forces (``efc_force``): with a pyramidal friction cone, ``2 (dim -
1)`` non-negative edge forces whose sum is the normal force and whose pairwise differences times the friction
coefficients are the tangential ones (``mju_decodePyramid``); with an elliptic cone, the contact-frame force itself.
``mj_contactForce`` decodes one contact per Python call; this kernel decodes them all, rotates them to the world
(the contact frame's rows are its axes, normal first) and sums force and moment about the world origin per sole.
A test checks it against ``mj_contactForce``.

The contacts are read where MuJoCo keeps them: `ContactRecords` views the records (``mjContact``) in the data's
arena once, as float64 and int32 rows, instead of making six field arrays every tick (about 1 us each through the
bindings).
"""

import ctypes

import numpy as np

from ..jit import njit

__all__ = ["ContactRecords", "sole_wrenches"]

#: the mjContact fields the kernel reads, in the order of `ContactRecords.offsets`
_FIELDS = ("efc_address", "dim", "friction", "frame", "pos", "geom")


class ContactRecords:
    """MuJoCo's contact records of one `MjData`, viewed in place: `floats` and `ints` are (capacity, record
    size / 8) float64 and (capacity, record size / 4) int32 views of the same memory, `offsets` the fields'
    positions in their rows (`_FIELDS` order). MuJoCo keeps the contacts at the start of the data's arena, which
    is allocated with the data: the views stay valid for the data's life. Built from the first contact seen
    (the fields' addresses say where the records and each field are); `matches(data)` checks them again."""

    def __init__(self, data):
        con = data.contact
        if data.ncon < 1:
            raise ValueError("contact records are located from a contact; there is none")
        self.data = data  # keeps the memory alive
        fields = {name: getattr(con, name) for name in _FIELDS + ("dist",)}
        stride = con.dim.strides[0]
        base = min(a.ctypes.data for a in fields.values())
        if stride % 8 or base % 8:
            raise ValueError("unexpected contact record layout")
        capacity = int(data.narena) // stride
        mem = (ctypes.c_char * (capacity * stride)).from_address(base)
        self.floats = np.frombuffer(mem, dtype=np.float64).reshape(capacity, stride // 8)
        self.ints = np.frombuffer(mem, dtype=np.int32).reshape(capacity, stride // 4)
        offsets = []
        for name in _FIELDS:
            off = fields[name].ctypes.data - base
            size = 4 if fields[name].dtype == np.int32 else 8
            if off % size:
                raise ValueError(f"unexpected contact record layout ({name})")
            offsets.append(off // size)
        self.offsets = np.array(offsets, dtype=np.int64)
        self.base = base

    def matches(self, data) -> bool:
        """True when `data`'s contacts still start where these views look (checked on a contact)."""
        return data is self.data and (data.ncon < 1 or data.contact.dim.ctypes.data - self.base
                                       == 4 * self.offsets[1])


@njit
def sole_wrenches(n, efc_force, floats, ints, offsets, soles, pyramidal, out):
    """Fill ``out`` (len(soles), 6) with the wrench (force, moment about the world origin) that the first ``n``
    contacts exert on each sole geom, world axes [N, N m]. ``floats``, ``ints``, ``offsets``: the contact records
    (`ContactRecords`); the force acts from ``geom[0]`` on ``geom[1]``. ``pyramidal``: the model's cone type.
    Contacts with ``efc_address < 0`` (excluded) carry no force."""
    out[:] = 0.0
    o_adr, o_dim, o_fric, o_frame, o_pos, o_geom = offsets[0], offsets[1], offsets[2], offsets[3], offsets[4], offsets[5]
    local = np.zeros(3)
    sgn = np.zeros(soles.shape[0])
    for i in range(n):
        rf = floats[i]
        ri = ints[i]
        g0, g1 = ri[o_geom], ri[o_geom + 1]
        sgn[:] = 0.0
        hit = False
        for k in range(soles.shape[0]):
            if g0 == soles[k]:
                sgn[k] = -1.0
                hit = True
            elif g1 == soles[k]:
                sgn[k] = 1.0
                hit = True
        adr = ri[o_adr]
        if not hit or adr < 0:
            continue
        d = ri[o_dim]
        local[:] = 0.0
        if pyramidal:
            if d == 1:
                local[0] = efc_force[adr]
            else:
                s = 0.0
                for j in range(2 * (d - 1)):
                    s += efc_force[adr + j]
                local[0] = s
                for j in range(min(d - 1, 2)):
                    local[j + 1] = (efc_force[adr + 2 * j] - efc_force[adr + 2 * j + 1]) * rf[o_fric + j]
        else:
            for j in range(min(d, 3)):
                local[j] = efc_force[adr + j]
        fr = o_frame
        f0 = rf[fr] * local[0] + rf[fr + 3] * local[1] + rf[fr + 6] * local[2]
        f1 = rf[fr + 1] * local[0] + rf[fr + 4] * local[1] + rf[fr + 7] * local[2]
        f2 = rf[fr + 2] * local[0] + rf[fr + 5] * local[1] + rf[fr + 8] * local[2]
        p0, p1, p2 = rf[o_pos], rf[o_pos + 1], rf[o_pos + 2]
        for k in range(soles.shape[0]):
            if sgn[k] == 0.0:
                continue
            h0, h1, h2 = sgn[k] * f0, sgn[k] * f1, sgn[k] * f2
            out[k, 0] += h0
            out[k, 1] += h1
            out[k, 2] += h2
            out[k, 3] += p1 * h2 - p2 * h1
            out[k, 4] += p2 * h0 - p0 * h2
            out[k, 5] += p0 * h1 - p1 * h0
