"""Contact correction of a predicted frame (runtime switch ``contact_correction``): a particle whose
step passed a kinematic particle is stopped at it, then overlapping particles are pushed apart along
their centre line until every overlap is at most the allowed one (plus an optional tolerance).

A learned rollout lets particles overlap far more than the DEM does (the DEM's largest overlap is
about 0.01 of the smaller radius; an untreated surrogate's reaches radii). A pair i < j of particles
with radii r_i, r_j and centre distance d overlaps too much when

    e_ij = r_i + r_j - a * min(r_i, r_j) - d > 0                  (a: ``allowed_overlap``)

and is then moved apart along n_ij = (x_j - x_i) / d (the first axis where d = 0, so coincident
particles separate without NaN) by the excess e_ij, split inversely to mass, with the mass taken as
r^D (equal densities, D the dimension) and a kinematic particle's inverse mass zero:

    w_i = m_i^-1 / (m_i^-1 + m_j^-1),   dx_i -= w_i e_ij n_ij,   dx_j += w_j e_ij n_ij.

A moving particle whose partner is kinematic thus takes the whole push; a kinematic one never
moves; two moving particles of equal radii move half the excess each, keeping their centre of mass.

One iteration is a Jacobi sweep: every pair's push is computed from the same positions, each
particle's pushes are averaged over its n_i corrected pairs (x_i += sum_j dx_i / n_i: two pushes
towards one another do not add up to an overshoot), then applied at once. The averaging keeps
the centre of mass only where the particles of a cluster have as many corrected pairs each; it
converges more slowly than summed pushes (a chain of three overlapping neighbours against a wall
takes about 40 sweeps, a cluster of four about 10, the 35 moving particles of a small slide sim
squeezed to 0.85 of their spread, 57 pairs too deep, about 500 to 1 000), but where the box and the kinematic particles
leave too little room to remove every overlap, the largest overlap grew with the sweeps far more with
summed pushes (a 20 x 20 square lattice of unit discs at spacing 1.8 inside fixed walls: from 0.25
to 1.0 radii in 200 sweeps summed, to 0.40 averaged). With the box given, the
moving particles are then put back into it (as ``keep_in_domain`` does), so the correction never
pushes a particle out. ``iterations`` sweeps at most; the sweeps stop early once no pair overlaps
by more than the allowed overlap plus ``tolerance`` (a fraction of the smaller radius, as ``a``).
Every sweep still pushes each pair deeper than ``a`` to ``a``; the tolerance only ends them. Without it
(0) a deep pile never ends early: a pushed pair lands exactly on the allowance and its neighbours'
pushes move it back by rounding, so every frame with a few deep pairs runs every sweep.

Pairs are searched with a Verlet list, as DEM codes search contacts: the pairs closer than
2 max(r) + s (no pair closer than r_i + r_j is farther apart than 2 max(r)), with the skin
s = ``SKIN`` max(r), are found once by the radius graph's search (:mod:`surrogate.graph`), leaving
out pairs of two kinematic particles, and each sweep measures only those. The list is searched
anew once a particle has moved more than s / 2 since the search: until then no two particles
have closed in by more than s, so no pair closer than 2 max(r) is missing, and the sweeps find
exactly the pairs a search every sweep would find (test). The skin trades the pairs measured per
sweep against the searches.

**A kinematic particle is not passed through** (:func:`stop_at_kinematic`, before the sweeps, where the
rollout gives the frame before the step). A learned step can carry a fast particle through a wall in
one frame (a disc falling 2 radii per frame onto a floor of fixed discs went between them, the
box put it back under them, and the sweeps then pushed it along the wrong centre line, down, for the
rest of the rollout: an overlap of 0.65 radii the sweeps can never remove). The sweeps see only where
a particle ends, so the path is tested: a moving particle i and a kinematic particle k move in
straight lines from the frame before to the prediction, their relative position p(s) = p_0 + s d,
0 <= s <= 1, and the path enters the allowed distance c = r_i + r_k - a min(r_i, r_k) at the
smallest root s* of |p_0 + s d| = c; a particle that starts inside it (|p_0| < c: one resting on a
wall, within the sweeps' rounding or tolerance) is in contact from s* = 0, at p(0) = p_0. Where its
end p_1 = p_0 + d lies past k (p_1 . n < 0, n = p(s*) / |p(s*)| the normal where the contact began),
the sweeps' push along the end's centre line would complete the passage (or, with p_1 outside c
again, not see it), so i is stopped where the contact began and the rest of its relative step
slides on along the contact (the normal part removed, as a wall takes it):

    p_1' = p(s*) + (1 - s*) (d - (d . n) n).

Of several such partners the first one met (smallest s*) stops i; what remains is left to the sweeps
(the slid rest of the step is not tested again, and a partner met earlier that i does not pass does
not stop it).
Paths that end on the near side of k are the sweeps' (a particle pressed into a wall is pushed out
along its centre line, as before; one that grazes a wall's reach in a sliding step is left as it
is), so the test changes nothing where no particle passes a wall.
Pairs of moving particles are not tested: both are predicted, and neither is a wall. The pairs are
searched once, within 2 max(r) plus the largest moving and kinematic steps of the frame, at most
``PATH_REACH`` max(r) in all: where a moving and a kinematic step add up to more than
``PATH_REACH`` - 2 max(r) (a blown-up rollout), the pair is tested only if it ends within that reach.
"""

from __future__ import annotations

from typing import NamedTuple

import torch

from surrogate.graph import radius_pairs

SKIN = 0.5          # the Verlet list's skin s, in units of the largest radius (module docstring)
PATH_REACH = 8.0    # the farthest the path test searches its pairs, in largest radii (module docstring)


def overlap_pairs(position: torch.Tensor, radius: torch.Tensor, moving: torch.Tensor,
                  reach: float | None = None) -> torch.Tensor:
    """[2, P] pairs, each once, at least one of them moving, whose centres are closer than ``reach``
    (by default 2 max(r), the farthest two particles can be apart and still overlap)."""
    return radius_pairs(position, 2 * float(radius.max()) if reach is None else reach, ~moving)


def correct_overlaps(position: torch.Tensor, radius: torch.Tensor, moving: torch.Tensor, allowed_overlap: float,
                     iterations: int, lower: torch.Tensor | None = None,
                     upper: torch.Tensor | None = None, *, skin: float = SKIN,
                     tolerance: float = 0.0) -> tuple[torch.Tensor, int]:
    """``position`` [N, D] with the overlaps above ``allowed_overlap`` (a fraction of the smaller
    radius) pushed apart in at most ``iterations`` Jacobi sweeps (module docstring), the moving
    particles kept in the box ``[lower, upper]`` when it is given; ``radius`` [N], ``moving`` [N]
    bool; ``skin`` the Verlet list's, in largest radii (0: a search before every sweep that follows
    motion); ``tolerance`` ends the sweeps once no pair overlaps more than ``allowed_overlap`` plus it
    (module docstring). Returns the corrected positions (a new tensor; ``position`` is left as it is) and the
    number of pairs that overlapped too much (by more than ``allowed_overlap`` plus ``tolerance``) before
    the correction."""
    if allowed_overlap < 0 or iterations < 1 or skin < 0 or tolerance < 0:
        raise ValueError(f"contact correction: allowed_overlap = {allowed_overlap!r} must be >= 0, "
                         f"iterations = {iterations!r} >= 1, skin = {skin!r} >= 0 and tolerance = "
                         f"{tolerance!r} >= 0")
    x = position.clone()
    n, dim = x.shape
    if n < 2 or not bool(moving.any()):
        return x, 0
    r = radius.to(device=x.device, dtype=x.dtype)
    inverse_mass = torch.where(moving, r.pow(-dim), torch.zeros_like(r))
    lo = None if lower is None else lower.to(x)
    hi = None if upper is None else upper.to(x)
    first_axis = torch.zeros(dim, dtype=x.dtype, device=x.device)
    first_axis[0] = 1
    skin = skin * float(r.max())
    reach = 2 * float(r.max()) + skin
    found, listed_at = 0, None
    for sweep in range(iterations):
        if listed_at is None or float((x - listed_at).norm(dim=-1).max()) > skin / 2:
            listed_at = x.clone()
            i, j = overlap_pairs(x, r, moving, reach)
            ri, rj = r.index_select(0, i), r.index_select(0, j)
            closest = ri + rj - allowed_overlap * torch.minimum(ri, rj)     # the allowed centre distance
            slack = tolerance * torch.minimum(ri, rj)
            mi, mj = inverse_mass.index_select(0, i), inverse_mass.index_select(0, j)
            share_i, share_j = mi / (mi + mj), mj / (mi + mj)             # mi + mj > 0: a moving particle
            counts_i, counts_j = (mi > 0).to(x.dtype), (mj > 0).to(x.dtype)
        gap = x.index_select(0, j) - x.index_select(0, i)
        distance = gap.norm(dim=-1)
        excess = closest - distance
        over = excess > 0
        beyond = excess > slack                                           # too deep, past the tolerance
        if sweep == 0:
            found = int(beyond.sum())
        if not bool(beyond.any()):
            break
        normal = torch.where((distance > 0).unsqueeze(-1), gap / distance.clamp(min=torch.finfo(x.dtype).tiny)
                             .unsqueeze(-1), first_axis)
        push = excess.clamp(min=0).unsqueeze(-1) * normal                 # zero for the pairs not too deep
        shift = torch.zeros_like(x)
        shift.index_add_(0, i, -share_i.unsqueeze(-1) * push)
        shift.index_add_(0, j, share_j.unsqueeze(-1) * push)
        pairs = torch.zeros(n, dtype=x.dtype, device=x.device)
        pairs.index_add_(0, i, counts_i * over)
        pairs.index_add_(0, j, counts_j * over)
        x += shift / pairs.clamp(min=1).unsqueeze(-1)
        if lo is not None and hi is not None:
            x[moving] = torch.maximum(torch.minimum(x[moving], hi), lo)
    return x, found


class Passages(NamedTuple):
    """The (moving, kinematic) pairs whose relative path passed (module docstring), one row per pair:
    ``particle`` the moving one, ``partner`` the kinematic one, ``s`` the fraction of the step at which the
    contact began, ``step`` the relative step d, ``contact`` the relative position p(s*) there and ``normal``
    n = p(s*) / |p(s*)|."""

    particle: torch.Tensor
    partner: torch.Tensor
    s: torch.Tensor
    step: torch.Tensor
    contact: torch.Tensor
    normal: torch.Tensor


def kinematic_passages(previous: torch.Tensor, position: torch.Tensor, radius: torch.Tensor, moving: torch.Tensor,
                       allowed_overlap: float) -> Passages:
    """Every pair of a moving and a kinematic particle whose straight relative path from ``previous`` [N, D] to
    ``position`` [N, D] entered (or started inside) their allowed distance c = r_i + r_k - ``allowed_overlap``
    min(r_i, r_k) and ended past the partner (module docstring): the path test of :func:`stop_at_kinematic`,
    also the plausibility measure ``Through wall`` (with ``allowed_overlap`` 0, the contact distance)."""
    x = position
    kinematic = ~moving
    r = radius.to(device=x.device, dtype=x.dtype)
    empty = torch.zeros(0, dtype=torch.long, device=x.device)
    none = Passages(empty, empty, x.new_zeros(0), x.new_zeros(0, x.shape[-1]), x.new_zeros(0, x.shape[-1]),
                    x.new_zeros(0, x.shape[-1]))
    if not bool(kinematic.any()) or not bool(moving.any()):
        return none
    before = previous.to(x)
    step = x - before
    length = step.norm(dim=-1)
    largest = float(r.max())
    reach = min(2 * largest + float(length[moving].max()) + float(length[kinematic].max()), PATH_REACH * largest)
    a, b = radius_pairs(x, reach, kinematic)
    a_moves = moving.index_select(0, a)
    mixed = a_moves ^ moving.index_select(0, b)
    i = torch.where(a_moves, a, b)[mixed]                               # the moving one of each pair
    k = torch.where(a_moves, b, a)[mixed]                               # its kinematic partner
    ri, rk = r.index_select(0, i), r.index_select(0, k)
    c = ri + rk - allowed_overlap * torch.minimum(ri, rk)
    p0 = before.index_select(0, i) - before.index_select(0, k)
    d = step.index_select(0, i) - step.index_select(0, k)
    dd, pd, pp = (d * d).sum(-1), (p0 * d).sum(-1), (p0 * p0).sum(-1)
    root = pd * pd - dd * (pp - c * c)
    s = (-pd - root.clamp(min=0).sqrt()) / dd.clamp(min=torch.finfo(x.dtype).tiny)
    inside = pp < c * c                                                 # in contact from the start: s* = 0
    s = torch.where(inside, torch.zeros_like(s), s)
    meets = (c > 0) & (dd > 0) & (inside & (pp > 0) | (pd < 0) & (root >= 0) & (s <= 1))   # c <= 0: no contact
    contact = p0 + s.unsqueeze(-1) * d
    normal = contact / contact.norm(dim=-1, keepdim=True).clamp(min=torch.finfo(x.dtype).tiny)
    passes = meets & (((p0 + d) * normal).sum(-1) < 0)
    if not bool(passes.any()):
        return none
    return Passages(i[passes], k[passes], s[passes], d[passes], contact[passes], normal[passes])


def stop_at_kinematic(previous: torch.Tensor, position: torch.Tensor, radius: torch.Tensor, moving: torch.Tensor,
                      allowed_overlap: float, lower: torch.Tensor | None = None,
                      upper: torch.Tensor | None = None) -> tuple[torch.Tensor, int]:
    """``position`` [N, D] with every moving particle whose path from ``previous`` [N, D] passed a
    kinematic particle stopped where it met it and slid along the contact (module docstring), kept in
    the box ``[lower, upper]`` where it is given. Returns the positions (a new tensor) and the number of
    particles stopped."""
    x = position.clone()
    passed = kinematic_passages(previous, x, radius, moving, allowed_overlap)
    if not len(passed.particle):
        return x, 0
    order = torch.argsort(passed.s, stable=True)                        # of a particle's partners, the first met
    i, k, s, d, contact, normal = (t[order] for t in passed)
    stopped, slot = torch.unique(i, return_inverse=True)
    first = torch.full_like(stopped, len(i)).scatter_reduce(0, slot, torch.arange(len(i), device=x.device), "amin")
    k, s, d, contact, normal = (t[first] for t in (k, s, d, contact, normal))
    along = d - (d * normal).sum(-1, keepdim=True) * normal             # the step's part along the contact
    x[stopped] = x.index_select(0, k) + contact + (1 - s).unsqueeze(-1) * along
    if lower is not None and upper is not None:
        x[stopped] = torch.maximum(torch.minimum(x[stopped], upper.to(x)), lower.to(x))
    return x, int(stopped.numel())
