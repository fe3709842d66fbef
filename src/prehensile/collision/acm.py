"""Allowed-collision matrices: which pairs of a robot's links are never checked.

An (L, L) bool matrix over ``model.link_names``; ``True`` means the pair is *allowed* to touch
(skipped by the checkers). A pair is skipped when the links

- belong to the same rigid body (connected only through fixed joints),
- are adjacent (their rigid bodies are joined by one moving joint),
- are listed as disabled in the SRDF (``model.disabled_collision_pairs``),
- involve a link without collision geometry,

or, for :func:`compute_acm`, when sampling finds the pair never or always in contact.
"""

from __future__ import annotations

from typing import Iterable

import numpy as np

from prehensile.model.robot_model import FIXED, RobotModel


def rigid_bodies(model: RobotModel) -> np.ndarray:
    """(L,) int64 rigid-body id per link: links joined by fixed joints share the id of the
    top-most of them."""
    body = np.arange(model.n_links, dtype=np.int64)
    for i in range(model.n_links):  # parents first, so the parent's id is final
        parent = int(model.link_parent[i])
        if parent >= 0 and int(model.joint_type[i]) == FIXED:
            body[i] = body[parent]
    return body


def allowed_collision_matrix(
    model: RobotModel, srdf: bool = True, adjacent: bool = True,
    extra_pairs: Iterable[tuple[str, str]] = (),
) -> np.ndarray:
    """The (L, L) bool matrix of link pairs that are not checked (symmetric, diagonal True).

    Args:
        model: the robot.
        srdf: skip the pairs in ``model.disabled_collision_pairs``.
        adjacent: skip links whose rigid bodies are joined by one moving joint.
        extra_pairs: further (link, link) names to skip.

    Raises:
        UnknownFrameError: a name in ``extra_pairs`` is not a link of the model.
    """
    n = model.n_links
    body = rigid_bodies(model)
    allowed = body[:, None] == body[None, :]
    if adjacent:
        for i in range(n):
            parent = int(model.link_parent[i])
            if parent >= 0 and int(model.joint_type[i]) != FIXED:
                a, b = body == body[i], body == body[parent]
                allowed |= a[:, None] & b[None, :]
                allowed |= b[:, None] & a[None, :]
    pairs = list(extra_pairs)
    if srdf:
        pairs += [tuple(p) for p in model.disabled_collision_pairs]
    for a, b in pairs:
        i, j = model.link_index(a), model.link_index(b)
        allowed[i, j] = allowed[j, i] = True
    empty = np.array([len(c) == 0 for c in model.collisions])
    allowed[empty, :] = True
    allowed[:, empty] = True
    return allowed


def compute_acm(
    model: RobotModel, n_samples: int = 2000, rng: np.random.Generator | int = 0,
    adjacent: bool = True,
) -> np.ndarray:
    """An allowed-collision matrix found by sampling, as MoveIt's setup assistant does.

    ``n_samples`` uniform configurations are checked with the exact meshes
    (:class:`~prehensile.collision.exact.ExactChecker`); pairs in contact in none of them
    ("never") or in all of them ("always") are allowed, as are same-body, adjacent (if
    ``adjacent``) and geometry-less pairs. The SRDF's list is not used. More samples make
    "never" more trustworthy (MoveIt uses 10,000 and more).

    Returns:
        (L, L) bool, True where the pair is skipped.
    """
    from prehensile.collision.exact import ExactChecker

    base = allowed_collision_matrix(model, srdf=False, adjacent=adjacent)
    checker = ExactChecker(model, [], acm=base)
    counts = np.zeros((model.n_links, model.n_links), dtype=np.int64)
    for q in model.random_configurations(rng, int(n_samples)):
        counts += checker.self_contacts(q)
    never_or_always = (counts == 0) | (counts == int(n_samples))
    allowed = base | never_or_always
    return allowed | allowed.T
