"""Static pictures of scenes with matplotlib (Agg): robots, obstacles, objects, collisions.

Every shape is turned into triangles (:func:`~prehensile.model.geometry.shape_to_trimesh`),
big meshes are decimated by vertex clustering, all triangles of a view go into one
``Poly3DCollection`` (so matplotlib depth-sorts them together) and are shaded with a fixed
light. Colliding links and bodies are drawn red and labelled.
"""

from __future__ import annotations

import io
import os
from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np

from trimesh.remesh import subdivide_to_size

from prehensile.model.geometry import Geometry, shape_to_trimesh
from prehensile.scene.scene import Scene
from prehensile.storage import atomic_write_bytes

ROBOT_COLORS = ("#8fa3bf", "#a993c4", "#7fb0b8", "#c49bb4", "#9aa7b0")  # the scene's robots in turn
PATH_START, PATH_GOAL = ("#4f7cc4", "blue"), ("#dd8a36", "orange")  # a path's robot copies blend from one to the other
IDLE_ROBOT_COLOR = "#cfcfcf"  # robots beside a drawn path
OBSTACLE_COLOR = "#c8b28a"
OBJECT_COLOR = "#6fae6f"
COLLISION_COLOR = "#e0261b"
DEFAULT_VIEWS = ((22.0, -60.0), (30.0, -128.0))
BODY_HIT_COLOR = "#e9b09a"
FLOOR_COLOR = "#e6e6e6"
_MAX_EDGE = 0.08  # m
_LIGHT = np.array([0.35, -0.45, 0.82]) / np.linalg.norm([0.35, -0.45, 0.82])


def robot_color(index: int) -> str:
    """Hex colour of the scene's robot ``index`` in pictures (the palette repeats)."""
    return ROBOT_COLORS[index % len(ROBOT_COLORS)]


def path_colors(count: int) -> list[str]:
    """Hex colours of ``count`` robot copies along a path: :data:`PATH_START` to :data:`PATH_GOAL`."""
    from matplotlib.colors import to_hex, to_rgb

    start, goal = np.array(to_rgb(PATH_START[0])), np.array(to_rgb(PATH_GOAL[0]))
    return [to_hex(start + t * (goal - start)) for t in np.linspace(0.0, 1.0, count)]


def decimate(vertices: np.ndarray, faces: np.ndarray, max_faces: int) -> tuple[np.ndarray, np.ndarray]:
    """Reduce a triangle mesh to about ``max_faces`` faces by vertex clustering.

    Vertices are snapped to a grid whose cell shrinks until the face count fits; faces that
    collapse are dropped. Good enough for drawing, not for geometry.

    Args:
        vertices: (n, 3) positions.
        faces: (m, 3) vertex indices.
        max_faces: target face count.

    Returns:
        (vertices (n', 3), faces (m', 3)) with m' <= max(max_faces, a handful).
    """
    if len(faces) <= max_faces:
        return vertices, faces
    extent = float(np.max(np.ptp(vertices, axis=0))) or 1.0
    best = None
    for cells in (40, 28, 20, 14, 10, 7, 5, 3):
        cell = extent / cells
        keys = np.floor((vertices - vertices.min(axis=0)) / cell).astype(np.int64)
        _, cluster, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
        cluster = cluster.ravel()
        centers = np.zeros((counts.size, 3))
        np.add.at(centers, cluster, vertices)
        centers /= counts[:, None]
        new_faces = cluster[faces]
        keep = (new_faces[:, 0] != new_faces[:, 1]) & (new_faces[:, 1] != new_faces[:, 2]) & (new_faces[:, 0] != new_faces[:, 2])
        new_faces = np.unique(np.sort(new_faces[keep], axis=1), axis=0) if keep.any() else new_faces[:0]
        best = (centers, new_faces)
        if len(new_faces) <= max_faces:
            break
    return best


def _triangles(geometry: Geometry, T_world_geom: np.ndarray, max_faces: int, cache: dict) -> np.ndarray:
    """World-space triangles (m, 3, 3) of a placed geometry; meshes cached per shape object."""
    key = id(geometry.shape)
    if key not in cache:
        mesh = shape_to_trimesh(geometry.shape, sections=16)
        vertices, faces = decimate(np.asarray(mesh.vertices, dtype=float), np.asarray(mesh.faces), max_faces)
        if len(faces) and len(faces) <= max_faces:
            # Split long triangles (table tops, shelf boards): matplotlib depth-sorts by
            # triangle centroid, so big triangles would be drawn over small parts inside them.
            vertices, faces = subdivide_to_size(vertices, faces, max_edge=_MAX_EDGE)
        cache[key] = (geometry.shape, vertices, faces)
    _, vertices, faces = cache[key]
    world = vertices @ T_world_geom[:3, :3].T + T_world_geom[:3, 3]
    return world[faces]


def _shade(triangles: np.ndarray, color: str) -> np.ndarray:
    """RGBA per triangle, Lambert-shaded with a fixed light (two-sided)."""
    from matplotlib.colors import to_rgba

    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    norms = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = normals / np.where(norms > 0, norms, 1.0)
    intensity = 0.45 + 0.55 * np.abs(normals @ _LIGHT)
    rgba = np.tile(np.array(to_rgba(color)), (len(triangles), 1))
    rgba[:, :3] *= intensity[:, None]
    return rgba


def scene_triangles(
    scene: Scene,
    colliding_links: Mapping[str, Iterable[str]] | None = None,
    colliding_bodies: Iterable[str] = (),
    kind: str = "collision",
    max_faces: int = 300,
    robot_colors: Mapping[str, str] | None = None,
) -> tuple[np.ndarray, np.ndarray, list[tuple[str, np.ndarray]]]:
    """All triangles of ``scene`` with their colours, and label anchors for colliding parts.
    A link geometry at the very pose where an earlier robot of the same model has it (copies
    of a robot along a path, where the joints not planned hold still) is drawn once.

    Args:
        scene: robots are drawn at their configurations.
        colliding_links: robot name -> links to draw red.
        colliding_bodies: scene bodies to draw red.
        kind: "collision" or "visual" robot geometry.
        max_faces: decimation target per mesh.
        robot_colors: robot name -> colour (hex) instead of :func:`robot_color` of its index.

    Returns:
        (triangles (m, 3, 3) in m, rgba (m, 4), [(label, anchor point (3,))]).
    """
    colliding_links = {r: set(links) for r, links in (colliding_links or {}).items()}
    colliding_bodies = set(colliding_bodies)
    cache: dict = {}
    parts: list[tuple[np.ndarray, str]] = []
    labels: list[tuple[str, np.ndarray]] = []
    drawn: set[tuple] = set()  # (model, link, geometry, pose) already drawn
    for r, robot in enumerate(scene.robots):
        red = colliding_links.get(robot.name, set())
        color = (robot_colors or {}).get(robot.name) or robot_color(r)
        per_link: dict[str, list[np.ndarray]] = {}
        for g, (link, geometry, T) in enumerate(robot.world_geometries(kind)):
            key = (id(robot.model), link, g, np.asarray(T).tobytes())
            if key in drawn and link not in red:
                continue
            drawn.add(key)
            per_link.setdefault(link, []).append(_triangles(geometry, T, max_faces, cache))
        for link, tris in per_link.items():
            tris = np.concatenate(tris)
            parts.append((tris, COLLISION_COLOR if link in red else color))
            if link in red:
                labels.append((f"{robot.name}/{link}", tris.reshape(-1, 3).mean(axis=0)))
    for bodies, color in ((scene.obstacles, OBSTACLE_COLOR), (scene.objects, OBJECT_COLOR)):
        for body in bodies:
            tris = np.concatenate([_triangles(g, T, max_faces, cache) for g, T in body.world_geometries()])
            hit = body.name in colliding_bodies
            parts.append((tris, BODY_HIT_COLOR if hit else color))
            if hit:
                labels.append((body.name, tris.reshape(-1, 3).mean(axis=0)))
    if not parts:
        return np.zeros((0, 3, 3)), np.zeros((0, 4)), labels
    triangles = np.concatenate([t for t, _ in parts])
    rgba = np.concatenate([_shade(t, c) for t, c in parts])
    return triangles, rgba, labels


def render_scene(scene: Scene, path: str | os.PathLike, **options) -> Path:
    """Draw ``scene`` (:func:`scene_image` with ``options``) and save it atomically to ``path``
    (folders are created; the suffix gives the format, PNG without one); returns the path."""
    return atomic_write_bytes(path, scene_image(scene, image_format=Path(path).suffix.lstrip(".") or "png", **options))


def scene_image(
    scene: Scene,
    colliding_links: Mapping[str, Iterable[str]] | None = None,
    colliding_bodies: Iterable[str] = (),
    title: str = "",
    views: tuple[tuple[float, float], ...] = DEFAULT_VIEWS,
    kind: str = "collision",
    max_faces: int = 300,
    size: tuple[float, float] = (14.0, 7.0),
    dpi: int = 110,
    image_format: str = "png",
    robot_colors: Mapping[str, str] | None = None,
) -> bytes:
    """Draw ``scene`` from each of ``views`` side by side.

    Args:
        scene: the scene (robots at their configurations).
        colliding_links: robot name -> links drawn red and labelled.
        colliding_bodies: bodies drawn red and labelled.
        title: figure title.
        views: (elevation, azimuth) pairs in degrees, one subplot each.
        kind: "collision" or "visual" robot geometry.
        max_faces: decimation target per mesh (faces).
        size: figure size in inches (width, height).
        dpi: resolution in dots per inch.
        image_format: a matplotlib file format ("png", "svg", "pdf", ...).
        robot_colors: robot name -> colour (hex) instead of the palette's (:func:`robot_color`).

    Returns:
        The image file's bytes.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    triangles, rgba, labels = scene_triangles(scene, colliding_links, colliding_bodies, kind, max_faces, robot_colors)
    labels = _spread(labels)
    points = triangles.reshape(-1, 3) if len(triangles) else np.zeros((1, 3))
    lo, hi = points.min(axis=0), points.max(axis=0)
    lo[2] = min(lo[2], 0.0)
    center, half = (lo + hi) / 2.0, np.maximum((hi - lo) / 2.0, 0.05) * 1.05
    floor = floor_triangles(center, half)
    floor_rgba = _shade(floor, FLOOR_COLOR)
    all_triangles = np.concatenate([floor, triangles])
    all_rgba = np.concatenate([floor_rgba, rgba])
    fig = Figure(figsize=size, dpi=dpi)  # Agg canvas: no global backend, no pyplot state
    FigureCanvasAgg(fig)
    for k, (elev, azim) in enumerate(views):
        ax = fig.add_subplot(1, len(views), k + 1, projection="3d")
        # Edges in the face colour hide the hairline seams between adjacent triangles.
        ax.add_collection3d(Poly3DCollection(all_triangles, facecolors=all_rgba, edgecolors=all_rgba, linewidths=0.3))
        for text, anchor, at in labels:
            ax.plot(*np.stack([at, anchor]).T, color=COLLISION_COLOR, linewidth=0.8, zorder=10)
            ax.text(*anchor, text, color=COLLISION_COLOR, fontsize=8, fontweight="bold", zorder=10,
                    bbox={"facecolor": "white", "alpha": 0.7, "edgecolor": "none", "pad": 1.0})
        ax.set_xlim(center[0] - half[0], center[0] + half[0])
        ax.set_ylim(center[1] - half[1], center[1] + half[1])
        ax.set_zlim(center[2] - half[2], center[2] + half[2])
        ax.set_box_aspect(tuple(2 * half))
        ax.view_init(elev=elev, azim=azim)
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_zlabel("z [m]")
        ax.tick_params(labelsize=7)
    if title:
        fig.suptitle(title, fontsize=12)
    fig.subplots_adjust(left=0.01, right=0.99, bottom=0.02, top=0.93, wspace=0.02)
    image = io.BytesIO()
    fig.savefig(image, format=image_format)
    return image.getvalue()


def _spread(labels: list[tuple[str, np.ndarray]], lift: float = 0.25, gap: float = 0.08):
    """Place each label ``lift`` m above its part (and higher if it would overlap an earlier one).

    Returns (text, label position (3,), part position (3,)) triples; a line joins the two.
    """
    placed: list[tuple[str, np.ndarray, np.ndarray]] = []
    for text, at in labels:
        anchor = np.array(at, dtype=float) + [0.0, 0.0, lift]
        while any(np.linalg.norm(anchor - other) < gap for _, other, _ in placed):
            anchor[2] += gap
        placed.append((text, anchor, np.asarray(at, dtype=float)))
    return placed


def floor_triangles(center: np.ndarray, half: np.ndarray, tiles: int = 12) -> np.ndarray:
    """A tiled floor at z = 0 under the scene, (2 * tiles**2, 3, 3) triangles in m.

    Small tiles let matplotlib's per-triangle depth sort put the floor behind everything.
    """
    xs = np.linspace(center[0] - half[0], center[0] + half[0], tiles + 1)
    ys = np.linspace(center[1] - half[1], center[1] + half[1], tiles + 1)
    x0, y0 = np.meshgrid(xs[:-1], ys[:-1], indexing="ij")
    x1, y1 = np.meshgrid(xs[1:], ys[1:], indexing="ij")
    z = np.zeros_like(x0)
    a, b = np.stack([x0, y0, z], -1), np.stack([x1, y0, z], -1)
    c, d = np.stack([x1, y1, z], -1), np.stack([x0, y1, z], -1)
    first = np.stack([a, b, c], axis=-2).reshape(-1, 3, 3)
    second = np.stack([a, c, d], axis=-2).reshape(-1, 3, 3)
    return np.concatenate([first, second])
