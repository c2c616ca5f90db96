"""The simulated harbour: quay walls and a pier, moored boats, town buildings behind the
quays, drifting trash of the thesis's kinds (bottles, bags, boxes; thesis section 4.2 and
Table 6.1), moving vessels, and the USV's path with its wave motion.

The basin is built on `usvfast.lidar.simulator.harbour_scene` (its quay walls and the
boats moored along the eastern quay), shifted north, closed at the southern end, given a
pier and a breakwater with an entrance. Everything is in local NED metres around the USV's
start point (the origin); heights are metres above the water. `make_world(seed)` is
deterministic: the same seed gives the same world.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from usvfast._validate import instance
from usvfast.lidar.simulator import BOAT, Box, Wall, harbour_scene
from usvfast.sim.motion import DriftMotion, PathMotion, Waves, chaikin, point_segment_distance

#: Kinds of objects in the ground truth (truth.csv).
FLOAT_KINDS = ("bottle", "bag", "box")
TRUTH_KINDS = (*FLOAT_KINDS, "buoy", "vessel", "moored_boat")

#: Reference point of the harbour (Brattørkaia, Trondheim, where the thesis recorded D1/D3):
#: latitude deg, longitude deg, ellipsoidal height m of the USV's start point.
ORIGIN = (63.4397, 10.4025, 40.0)

#: Basin extent, m: quay lines at east = ±HALF_WIDTH, from SOUTH to NORTH.
HALF_WIDTH, SOUTH, NORTH = 20.0, -35.0, 125.0

# (length range m, width range m, top above water range m, colours BGR, reflectivity range)
_KIND_SPECS = {
    "bottle": (
        (0.20, 0.33),
        (0.07, 0.10),
        (0.05, 0.09),
        [(40, 160, 40), (200, 120, 30), (230, 230, 225), (60, 60, 200), (150, 200, 210)],
        (15, 40),
    ),
    "bag": (
        (0.30, 0.50),
        (0.25, 0.40),
        (0.03, 0.07),
        [(235, 235, 235), (40, 40, 40), (190, 110, 40), (60, 200, 230)],
        (8, 30),
    ),
    "box": (
        (0.25, 0.45),
        (0.20, 0.32),
        (0.10, 0.20),
        [(70, 120, 165), (190, 190, 195), (50, 50, 180), (220, 220, 220)],
        (30, 70),
    ),
}


@dataclass
class Body:
    """A shape of the scene with its identity: `shape` a simulator `Wall` or `Box`,
    `object_id` ('' for static structure), `kind` (a TRUTH_KIND, or 'wall' / 'building' /
    'boat_part'), `colour` BGR 0..255, `reflectivity` LiDAR intensity 0..255."""

    shape: Wall | Box
    object_id: str
    kind: str
    colour: tuple[int, int, int]
    reflectivity: float

    @property
    def box(self) -> Box:
        """The shape of a body that is a Box (movers' bodies, moored hulls); TypeError for a
        wall."""
        if not isinstance(self.shape, Box):
            raise TypeError(f"body {self.object_id!r}: expected a Box shape, got a Wall")
        return self.shape


@dataclass
class Mover:
    """A moving object: `object_id`, `kind`, its `motion` (PathMotion or DriftMotion) and the
    bodies that make it, in its own frame (x forward along its yaw, y starboard, m)."""

    object_id: str
    kind: str
    motion: PathMotion | DriftMotion
    bodies: list[Body]
    size: tuple[float, float, float]  # length, width, top above water, m


@dataclass
class World:
    """One simulated harbour.

    static : walls, pier, moored boats and buildings (world frame bodies).
    moored : the moored boats (object_id, kind 'moored_boat', one hull Box each).
    movers : floating objects and vessels.
    usv : the USV's path; waves : its roll, pitch and heave.
    origin : (lat deg, lon deg, height m) of the NED origin; duration : s the world was
    built for (floats are placed along the first part of the path).
    """

    seed: int
    duration: float
    static: list[Body]
    moored: list[Body]
    movers: list[Mover]
    usv: PathMotion
    waves: Waves
    walls: list[np.ndarray]
    origin: tuple[float, float, float] = ORIGIN
    sun_azimuth: float = 2.4
    sun_elevation: float = 0.6
    extra: dict = field(default_factory=dict)

    def bodies_at(self, t: float) -> list[Body]:
        """Every body in the world frame at time `t` s (static ones first)."""
        out = list(self.static)
        for m in self.movers:
            n, e, yaw = (float(v) for v in m.motion.pose(np.asarray(t)))
            out.extend(place_body(b, n, e, yaw) for b in m.bodies)
        return out

    def truth_ids(self) -> dict[str, int]:
        """Integer id (truth.csv `object_id`) of every truth object by name ('box0', ...):
        movers first, then moored boats, in world order."""
        names = [m.object_id for m in self.movers] + [b.object_id for b in self.moored]
        return {name: k for k, name in enumerate(names)}

    def truth_at(self, t: np.ndarray) -> list[tuple[str, str, np.ndarray, np.ndarray]]:
        """(object_id, kind, north (k,), east (k,)) of every truth object at times `t` (k,):
        floating objects, vessels, moored boats."""
        t = np.asarray(t, dtype=np.float64)
        out = []
        for m in self.movers:
            n, e, _ = m.motion.pose(t)
            out.append((m.object_id, m.kind, n, e))
        for b in self.moored:
            c = b.box.center
            out.append((b.object_id, b.kind, np.full(t.shape, c[0]), np.full(t.shape, c[1])))
        return out


def place_body(body: Body, north: float, east: float, yaw: float) -> Body:
    """A mover's body (a Box in the mover's frame) moved to (north, east) m with heading
    `yaw` rad."""
    instance("body", body, Body)
    s = body.box
    c, si = np.cos(yaw), np.sin(yaw)
    x, y = s.center
    centre = (north + c * x - si * y, east + si * x + c * y)
    shape = dataclasses.replace(s, center=centre, yaw=s.yaw + yaw)
    return dataclasses.replace(body, shape=shape)


def _colour(rng: np.random.Generator, choices: list[tuple[int, int, int]]) -> tuple[int, int, int]:
    base = np.asarray(choices[int(rng.integers(len(choices)))], dtype=np.float64)
    jitter = rng.uniform(0.85, 1.1)
    b, g, r = (int(v) for v in np.clip(base * jitter, 0, 255))
    return b, g, r


def _structure(rng: np.random.Generator, boats: int) -> tuple[list[Body], list[Body], list]:
    """Walls, pier, moored boats (harbour_scene's, shifted) and buildings."""
    base = harbour_scene(
        seed=int(rng.integers(2**31)),
        walls=2,
        boats=boats,
        floats=0,
        channel_width=2 * HALF_WIDTH,
        length=(NORTH - SOUTH) / 2,
    )
    shift = np.array([(NORTH + SOUTH) / 2, 0.0])
    static: list[Body] = []
    moored: list[Body] = []
    walls: list[np.ndarray] = []
    concrete = (150, 155, 160)
    for obj in base.objects:
        if isinstance(obj, Wall):
            poly = np.asarray(obj.polyline) + shift
            walls.append(poly)
            static.append(Body(Wall(poly, obj.height), "", "wall", concrete, 60.0))
        elif obj.kind == BOAT:
            c = (obj.center[0] + shift[0], obj.center[1])
            hull = dataclasses.replace(obj, center=c, top=1.1)
            k = len(moored)
            hull_colour = _colour(rng, [(235, 235, 235), (150, 80, 30), (40, 40, 150)])
            body = Body(hull, f"moored{k}", "moored_boat", hull_colour, 70.0)
            moored.append(body)
            static.append(body)
            cabin = dataclasses.replace(
                obj, center=c, length=obj.length * 0.4, width=obj.width * 0.7, top=1.9
            )
            static.append(Body(cabin, f"moored{k}", "boat_part", (200, 200, 200), 60.0))
    # southern quay, a breakwater with an entrance at the northern end, and a pier
    south = np.array([[SOUTH, -HALF_WIDTH], [SOUTH, HALF_WIDTH]])
    north_w = np.array([[NORTH, -HALF_WIDTH], [NORTH, -3.0]])
    north_e = np.array([[NORTH, 7.0], [NORTH, HALF_WIDTH]])
    n_pier = 30.0 + rng.uniform(-2.0, 2.0)
    pier = np.array(
        [
            [n_pier, -HALF_WIDTH],
            [n_pier, -9.0],
            [n_pier + 3.0, -9.0],
            [n_pier + 3.0, -HALF_WIDTH],
        ]
    )
    for poly, h in ((south, 2.0), (north_w, 2.5), (north_e, 2.5), (pier, 1.6)):
        walls.append(poly)
        static.append(Body(Wall(poly, h), "", "wall", concrete, 60.0))
    # buildings along both quays, set back from the edge
    for side in (-1.0, 1.0):
        n0 = SOUTH - 10.0
        while n0 < NORTH + 10.0:
            length = rng.uniform(10.0, 25.0)
            depth = rng.uniform(8.0, 14.0)
            setback = rng.uniform(6.0, 12.0)
            e = side * (HALF_WIDTH + setback + depth / 2)
            colour = _colour(
                rng, [(120, 140, 180), (90, 90, 160), (200, 200, 190), (150, 130, 110)]
            )
            shape = Box((n0 + length / 2, e), length, depth, 0.0, 0.0, rng.uniform(7.0, 16.0))
            static.append(Body(shape, "", "building", colour, 50.0))
            n0 += length + rng.uniform(2.0, 6.0)
    return static, moored, walls


def _usv_path(rng: np.random.Generator) -> PathMotion:
    """A zig-zag north through the basin, a turn at the breakwater and a return leg along the
    moored boats, looping (Chaikin-smoothed waypoints)."""
    amp = rng.uniform(8.0, 10.0)
    wp = [(0.0, 0.0)]
    n = 0.0
    side = 1.0
    while n < 95.0:
        n += rng.uniform(11.0, 14.0)
        wp.append((n, side * amp + rng.uniform(-1.0, 1.0) + 3.0))
        side = -side
    wp += [(108.0, 4.0), (110.0, 12.0), (95.0, 13.0), (60.0, 12.5), (20.0, 12.0), (-8.0, 10.0)]
    wp += [(-15.0, 2.0), (-10.0, -4.0)]
    verts = chaikin(np.array(wp), iterations=4, closed=True)
    # start exactly at the origin heading north: rotate the loop to the vertex nearest it
    k = int(np.argmin(np.hypot(verts[:, 0], verts[:, 1])))
    verts = np.roll(verts, -k, axis=0)
    verts = verts - verts[0]
    return PathMotion(verts, speed=rng.uniform(1.1, 1.3), speed_wobble=0.08, wobble_period=17.0)


def _vessel(rng: np.random.Generator, k: int) -> Mover:
    """A small motor boat on a loop through the basin, 1.5–2.5 m/s."""
    length = rng.uniform(5.0, 7.5)
    width = 2.2
    hull = Box((0.0, 0.0), length, width, 0.0, 0.0, 1.0)
    cabin = Box((-0.1 * length, 0.0), 0.35 * length, 0.7 * width, 0.0, 0.0, 1.8)
    colour = _colour(rng, [(240, 240, 240), (40, 40, 170), (160, 90, 20)])
    bodies = [
        Body(hull, f"vessel{k}", "vessel", colour, 70.0),
        Body(cabin, f"vessel{k}", "boat_part", (210, 210, 210), 60.0),
    ]
    if k == 0:  # along the western half, past the pier head, and back along the middle
        wp = [(115.0, -5.0), (60.0, -6.0), (10.0, -8.0), (-25.0, -5.0), (-20.0, 2.0), (80.0, 3.0)]
    else:  # crossing loops in the northern basin
        wp = [(80.0, -14.0), (95.0, 8.0), (115.0, 0.0), (100.0, -12.0)]
    verts = chaikin(np.array(wp), iterations=4, closed=True)
    motion = PathMotion(verts, speed=rng.uniform(1.5, 2.5), start=rng.uniform(0.0, 40.0) + 10.0 * k)
    return Mover(f"vessel{k}", "vessel", motion, bodies, (length, width, 1.0))


def _clearance(p: np.ndarray, walls: list[np.ndarray], moored: list[Body]) -> float:
    """Distance (m) from `p` to the nearest wall or moored hull (hull as its centre line
    minus half its width)."""
    d = min(point_segment_distance(p, w) for w in walls)
    for b in moored:
        s = b.box
        c, si = np.cos(s.yaw), np.sin(s.yaw)
        half = 0.5 * s.length * np.array([c, si])
        line = np.array([np.asarray(s.center) - half, np.asarray(s.center) + half])
        d = min(d, point_segment_distance(p, line) - s.width / 2)
    return d


def _inside(p: np.ndarray) -> bool:
    return bool(SOUTH < p[0] < NORTH and -HALF_WIDTH < p[1] < HALF_WIDTH)


def _floats(
    rng: np.random.Generator,
    count: int,
    usv: PathMotion,
    duration: float,
    walls: list[np.ndarray],
    moored: list[Body],
) -> list[Mover]:
    """`count` pieces of trash near the USV's path over the first `duration` s (2.5–9 m to
    either side), ≥ 4 m apart, ≥ 2 m from walls and boats, drifting with a common current."""
    span = max(duration, 20.0)
    tt = np.linspace(0.0, span, 400)
    pn, pe, _ = usv.pose(tt)
    path = np.column_stack([pn, pe])
    cur_dir = rng.uniform(0, 2 * np.pi)
    current = rng.uniform(0.02, 0.06) * np.array([np.cos(cur_dir), np.sin(cur_dir)])
    wind_dir = rng.uniform(0, 2 * np.pi)
    wind = np.array([np.cos(wind_dir), np.sin(wind_dir)])

    def allowed(q: np.ndarray) -> bool:
        return _inside(q) and _clearance(q, walls, moored) > 1.0

    placed: list[np.ndarray] = []
    movers: list[Mover] = []
    for _ in range(20000):
        if len(movers) == count:
            break
        t = rng.uniform(min(3.0, span / 4), span - min(5.0, span / 4))
        n, e, h = (float(v) for v in usv.pose(np.asarray(t)))
        lateral = rng.uniform(2.5, 9.0) * rng.choice([-1.0, 1.0])
        along = rng.uniform(-3.0, 3.0)
        p = np.array(
            [
                n + along * np.cos(h) - lateral * np.sin(h),
                e + along * np.sin(h) + lateral * np.cos(h),
            ]
        )
        if not _inside(p) or _clearance(p, walls, moored) < 2.0:
            continue
        if np.min(np.hypot(*(path - p).T)) < 2.5:
            continue
        if any(np.hypot(*(p - q)) < 4.0 for q in placed):
            continue
        kind = FLOAT_KINDS[int(rng.choice(3, p=[0.4, 0.3, 0.3]))]
        (l_lo, l_hi), (w_lo, w_hi), (h_lo, h_hi), colours, (r_lo, r_hi) = _KIND_SPECS[kind]
        length, width, top = (
            rng.uniform(l_lo, l_hi),
            rng.uniform(w_lo, w_hi),
            rng.uniform(h_lo, h_hi),
        )
        windage = wind * (0.03 if kind == "bag" else 0.015) * rng.uniform(0.5, 1.5)
        motion = DriftMotion.simulate(
            rng,
            (p[0], p[1]),
            duration + 1.0,
            current=current,
            windage=windage,
            yaw0=rng.uniform(0, np.pi),
            yaw_rate=np.radians(rng.uniform(-4.0, 4.0)),
            allowed=allowed,
        )
        k = len(movers)
        body = Body(
            Box((0.0, 0.0), length, width, 0.0, 0.0, top, kind),
            f"{kind}{k}",
            kind,
            _colour(rng, colours),
            float(rng.uniform(r_lo, r_hi)),
        )
        movers.append(Mover(f"{kind}{k}", kind, motion, [body], (length, width, top)))
        placed.append(p)
    if len(movers) < count:
        raise ValueError(f"floats: could only place {len(movers)} of {count} objects")
    return movers


def make_world(
    seed: int,
    duration: float = 60.0,
    *,
    floats: int | None = None,
    vessels: int | None = None,
    boats: int = 4,
) -> World:
    """Build the harbour of `seed` for a recording of `duration` s.

    floats : number of floating objects (default: 8–12 drawn from the seed; 5–15 allowed).
    vessels : moving vessels, 1 or 2 (default drawn from the seed).
    boats : boats moored along the eastern quay.
    Raises ValueError for counts out of range or a duration that is not positive.
    """
    if not duration > 0:
        raise ValueError(f"duration: expected > 0 s, got {duration}")
    rng = np.random.default_rng(seed)
    if floats is None:
        floats = int(rng.integers(8, 13))
    if not 0 <= floats <= 15:
        raise ValueError(f"floats: expected 0..15, got {floats}")
    if vessels is None:
        vessels = int(rng.integers(1, 3))
    if not 0 <= vessels <= 2:
        raise ValueError(f"vessels: expected 0..2, got {vessels}")
    static, moored, walls = _structure(rng, boats)
    usv = _usv_path(rng)
    waves = Waves.random(rng)
    movers = _floats(rng, floats, usv, min(duration, 60.0), walls, moored)
    movers += [_vessel(rng, k) for k in range(vessels)]
    return World(
        seed=seed,
        duration=float(duration),
        static=static,
        moored=moored,
        movers=movers,
        usv=usv,
        waves=waves,
        walls=walls,
        sun_azimuth=float(rng.uniform(0, 2 * np.pi)),
        sun_elevation=float(np.radians(rng.uniform(20.0, 45.0))),
    )
