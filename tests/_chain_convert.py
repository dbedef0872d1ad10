"""Convert a ctmm Chain of lumped elements into the independent GlobalChain reference.

Only element *parameters* are read (mass, stiffness, damping, free length); no transfer-matrix
code is used.  Supported: [boundary, (connector, point...)..., boundary] chains where every
mass is separated by exactly one connector; Elastic boundaries become a connector to a fixed wall.
"""
from __future__ import annotations

import numpy as np

import ctmm
from ctmm.elements import Connector, Elastic, Fixed, Free, GroundedSpring, Inerter, Mass, SpringDamper
from ctmm.reference import inerter_chain
from ctmm.reference.chain import GlobalChain


def to_global(chain: ctmm.Chain) -> GlobalChain:
    masses, k, c, l, kg, cg = [], [], [], [], [], []
    pending = None  # connector waiting for the next mass

    def boundary_connector(b):
        if isinstance(b, Elastic):
            return (b.stiffness, b.damping, 0.0), "fixed"
        if isinstance(b, Fixed):
            return None, "fixed"
        if isinstance(b, Free):
            return (0.0, 0.0, 0.0), "free"
        raise TypeError(b)

    first, start = boundary_connector(chain.start)
    pending = first
    for e in chain.body:
        if isinstance(e, Connector):
            if pending is not None and not (start == "free" and not masses):
                raise ValueError("two connectors in series are not supported by the converter")
            pending = (e.stiffness, e.damping, e.free_length)
        elif isinstance(e, Mass):
            if pending is None:
                raise ValueError("a mass must be preceded by a connector")
            k.append(pending[0]); c.append(pending[1]); l.append(pending[2])
            pending = None
            masses.append(e.mass); kg.append(0.0); cg.append(0.0)
        elif isinstance(e, GroundedSpring):
            kg[-1] += e.stiffness; cg[-1] += e.damping
        else:
            raise TypeError(e)
    last, end = boundary_connector(chain.end)
    if pending is not None:  # connector to the end boundary
        if end == "free" and not isinstance(chain.end, Free):
            raise ValueError
        k.append(pending[0]); c.append(pending[1]); l.append(pending[2])
        if isinstance(chain.end, Elastic):
            raise ValueError("connector followed by an elastic end is not supported")
    else:
        tail = last if last is not None else (0.0, 0.0, 0.0)
        k.append(tail[0]); c.append(tail[1]); l.append(tail[2])
    return GlobalChain(np.array(masses), np.array(k), np.array(c), np.array(l), np.array(kg),
                       np.array(cg), start=start, end=end)


def random_chain(rng: np.random.Generator, n: int, *, start: str, end: str, damped: bool = False,
                 grounded: bool = False) -> ctmm.Chain:
    """A random chain of ``n`` masses with the given end types ("fixed", "free", "elastic")."""
    def boundary(kind, name):
        if kind == "fixed":
            return Fixed(name)
        if kind == "free":
            return Free(name)
        return Elastic(name, float(rng.uniform(50, 500)), damping=float(rng.uniform(0, 1)) if damped else 0.0)

    elements = [boundary(start, "start")]
    for i in range(n):
        if not (i == 0 and start in ("free", "elastic")):
            kk = float(rng.uniform(50.0, 500.0))
            cc = float(rng.uniform(0.1, 2.0)) if damped else 0.0
            elements.append(ctmm.elements.SpringDamper(f"k{i}", kk, cc) if damped
                            else ctmm.elements.Spring(f"k{i}", kk))
        elements.append(Mass(f"m{i}", float(rng.uniform(0.2, 3.0))))
        if grounded and rng.uniform() < 0.3:
            elements.append(GroundedSpring(f"g{i}", float(rng.uniform(10, 100))))
    if end == "fixed":
        kk = float(rng.uniform(50.0, 500.0))
        elements.append(ctmm.elements.SpringDamper(f"k{n}", kk, float(rng.uniform(0.1, 2.0))) if damped
                        else ctmm.elements.Spring(f"k{n}", kk))
    elements.append(boundary(end, "end"))
    return ctmm.Chain(f"random_{start}_{end}_{n}", elements)


def inerter_chains(masses, k, c, b, end: str):
    """The same chain for ctmm and ``reference/inerter_chain.py`` (a zero mass: a point without a Mass;
    a connector without inertance: a SpringDamper)."""
    n = len(masses)
    if end == "free":
        k[n] = c[n] = b[n] = 0.0
    reference = inerter_chain.InerterChain(masses, k, c, b, start="fixed", end=end)
    elements = [Fixed("start")]
    for j in range(n + 1):
        if j == n and end == "free":
            break
        elements.append(Inerter(f"c{j}", b[j], stiffness=k[j], damping=c[j]) if b[j] else
                        SpringDamper(f"c{j}", k[j], c[j]))
        if j < n and masses[j]:
            elements.append(Mass(f"m{j}", masses[j]))
    return ctmm.Chain("inerters", elements + [Fixed("end") if end == "fixed" else Free("end")]), reference
