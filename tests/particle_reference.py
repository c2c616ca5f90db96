"""A plain numpy implementation of the particle filter's local-tier step (Bloisi et al. Fig. 9
and KClusterize, Fig. 10), written from the same description as the Rust core and drawing the
same counter-based random numbers (SplitMix64 of seed + (i + 1)·γ, Box–Muller), so that both
give the same numbers from the same seed. The oracle of tests/test_shore_particle.py and the
peer of benches/bench_shore.py."""

from __future__ import annotations

import numpy as np

GAMMA = np.uint64(0x9E3779B97F4A7C15)


def words(seed: int, start: int, n: int) -> np.ndarray:
    """Words start .. start + n of the stream of seed (uint64)."""
    i = np.arange(start + 1, start + n + 1, dtype=np.uint64)
    z = np.uint64(seed) + i * GAMMA
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


def uniforms(seed: int, start: int, n: int) -> np.ndarray:
    """Uniforms in [0, 1) from 53 bits of each word."""
    return (words(seed, start, n) >> np.uint64(11)).astype(np.float64) * 2.0**-53


def normals(seed: int, start: int, n: int) -> np.ndarray:
    """n standard normals by Box–Muller from words start .. start + 2n."""
    u = uniforms(seed, start, 2 * n).reshape(n, 2)
    return np.sqrt(-2.0 * np.log(1.0 - u[:, 0])) * np.cos(2 * np.pi * u[:, 1])


class Stream:
    """A position in the stream of one seed."""

    def __init__(self, seed: int) -> None:
        self.seed, self.counter = seed, 0

    def normals(self, n: int) -> np.ndarray:
        out = normals(self.seed, self.counter, n)
        self.counter += 2 * n
        return out

    def uniform(self) -> float:
        out = uniforms(self.seed, self.counter, 1)[0]
        self.counter += 1
        return float(out)


def propagate(p: np.ndarray, dt: float, accel_std: float, rng: Stream) -> np.ndarray:
    """Constant velocity with a random acceleration per particle and axis."""
    a = accel_std * rng.normals(2 * len(p)).reshape(-1, 2)
    out = p.copy()
    out[:, :2] += p[:, 2:] * dt + 0.5 * a * dt * dt
    out[:, 2:] += a * dt
    return out


def sample_around(count, centre, pos_std, velocity, vel_std, rng: Stream) -> np.ndarray:
    """count proposal particles (normals in the order u, v, du, dv per particle)."""
    z = rng.normals(4 * count).reshape(count, 4)
    return np.column_stack(
        [
            centre[0] + pos_std[0] * z[:, 0],
            centre[1] + pos_std[1] * z[:, 1],
            velocity[0] + vel_std * z[:, 2],
            velocity[1] + vel_std * z[:, 3],
        ]
    )


def weights(p: np.ndarray, obs: np.ndarray, clutter: float) -> np.ndarray:
    """Mixture likelihood of the observations [u, v, σu, σv] plus the clutter floor."""
    w = np.full(len(p), clutter)
    for z in obs:
        d2 = ((p[:, 0] - z[0]) / z[2]) ** 2 + ((p[:, 1] - z[1]) / z[3]) ** 2
        w = w + np.exp(-0.5 * d2) / (2 * np.pi * z[2] * z[3])
    return w


def resample(w: np.ndarray, n: int, rng: Stream) -> np.ndarray:
    """Systematic resampling: the j-th index is the first i with cumsum_i > (u0 + j)/n · total."""
    c = np.cumsum(w)
    u0 = rng.uniform()
    pos = (u0 + np.arange(n)) / n * c[-1]
    return np.minimum(np.searchsorted(c, pos, side="right"), len(w) - 1)


def _leader(p: np.ndarray, members: np.ndarray, delta: float) -> list[np.ndarray]:
    xy = p[members, :2]
    cents: list[int] = []
    far = np.ones(len(members), bool)
    while far.any():
        c = int(np.argmax(far))
        cents.append(c)
        far &= ((xy - xy[c]) ** 2).sum(1) > delta * delta
    d = np.stack([((xy - xy[c]) ** 2).sum(1) for c in cents], axis=1)
    lab = np.argmin(d, axis=1)
    return [members[lab == k] for k in range(len(cents))]


def kclusterize(p, w, delta, min_size=8, min_kurtosis=1.9, max_depth=3):
    """[(λ, mean (4,), std (4,), members)] as the Rust KClusterize."""
    total = w.sum()
    out = []

    def rec(members, delta, depth):
        for g in _leader(p, members, delta):
            wg = w[g]
            mean = (wg[:, None] * p[g]).sum(0) / wg.sum()
            std = np.sqrt((wg[:, None] * (p[g] - mean) ** 2).sum(0) / wg.sum())
            ok = len(g) >= min_size
            if ok and len(g) >= 8:
                for d in range(2):
                    if (
                        std[d] > 1e-9
                        and np.mean(((p[g, d] - mean[d]) / std[d]) ** 4) < min_kurtosis
                    ):
                        ok = False
            if ok:
                out.append((wg.sum() / total, mean, std, np.sort(g)))
            elif depth > 0 and len(g) >= min_size:
                rec(g, delta / 2, depth - 1)

    if len(p):
        rec(np.arange(len(p)), delta, max_depth)
    return out


def local_step(
    particles, obs, velocities, *, count, dt, accel_std, vel_std, clutter, n_out, delta, seed
):
    """The same step as usvfast._core.particle_local_step: (resampled, clusters)."""
    rng = Stream(seed)
    sets = [propagate(np.asarray(particles, float).reshape(-1, 4), dt, accel_std, rng)]
    for z, v in zip(obs, velocities, strict=True):
        sets.append(sample_around(count, z[:2], z[2:], v, vel_std, rng))
    s = np.concatenate(sets)
    idx = resample(weights(s, obs, clutter), n_out, rng)
    res = s[idx]
    return res, kclusterize(res, np.ones(len(res)), delta)
