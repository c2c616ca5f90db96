"""Day/night (EO colour vs IR grey) frame classifier of Kim, Chung and Lee (§II): a Gaussian
fitted to the frame's intensity histogram (mean and standard deviation, eq. 2; density eq. 3)
and a Bayes decision between the classes (eq. 1).

Features of a frame (8-bit levels): the mean m and standard deviation σ of its intensity
(eq. 2) and the mean chroma (max − min over the B, G, R channels of each pixel), which is what
separates a colour CCTV frame from a grey IR one. Each class holds a Gaussian per feature
(eq. 3, independent features) and a prior; the decision is the class of largest posterior
P(θ|F) ∝ P(F|θ) P(θ) (eq. 1).

The shipped class parameters: EO fitted on the MarDCT training frames; IR fitted on grey
copies of the same frames (no IR frames are available here), so the IR class is the
"no chroma" class. `DayNightClassifier.fit` refits both from the user's frames.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np

from usvfast._validate import as_float_array, finite_result
from usvfast._validate import image as check_image

FrameClass = Literal["eo", "ir"]
CLASSES: tuple[FrameClass, FrameClass] = ("eo", "ir")

#: Smallest standard deviation of a class feature (8-bit levels), so that a class fitted on
#: frames with a constant feature (IR chroma 0) keeps a proper density.
MIN_SIGMA = 1.0


#: Frames are sampled on a regular grid of about this many pixels for the features (their
#: mean and σ change by a small fraction of a level; a 704 × 576 frame costs 40 × less).
FEATURE_PIXELS = 10000


def frame_features(image: np.ndarray) -> np.ndarray:
    """(3,) features of a BGR or grey uint8 frame: intensity mean and standard deviation
    (eq. 2) and mean chroma (max − min channel), 8-bit levels, over the pixels of a regular
    grid of about `FEATURE_PIXELS` (every pixel of a frame up to twice that size)."""
    check_image("image", image)
    if image.ndim in (2, 3):
        step = max(1, int(np.sqrt(image.shape[0] * image.shape[1] / FEATURE_PIXELS)))
        image = np.ascontiguousarray(image[::step, ::step])
    if image.ndim == 2:
        gray, chroma = image, 0.0
    elif image.ndim == 3 and image.shape[2] == 3:
        gray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        b, g, r = cv2.split(image)
        spread = cv2.subtract(cv2.max(cv2.max(b, g), r), cv2.min(cv2.min(b, g), r))
        chroma = float(cv2.mean(spread)[0])
    else:
        raise ValueError(f"image: expected (h, w) or (h, w, 3), got shape {image.shape}")
    mean, std = cv2.meanStdDev(gray)  # σ = sqrt(Σ x² / n − m²)  (eq. 2)
    return np.array([float(mean[0, 0]), float(std[0, 0]), chroma])


def gaussian_density(x: np.ndarray, mu: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """f(x) = exp(−(x − μ)² / 2σ²) / sqrt(2πσ²)  (eq. 3), elementwise."""
    x = as_float_array("x", x)
    mu = as_float_array("mu", mu)
    sigma = as_float_array("sigma", sigma)
    if np.any(sigma <= 0):
        raise ValueError("sigma: must be > 0")
    # in z = (x − μ)/σ: a tiny σ squared no longer underflows to 0 (0/0); a density beyond
    # float64 (σ below ~1e-309) is an error naming sigma, never inf or NaN
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        z = (x - mu) / sigma
        f = np.exp(-0.5 * z * z) / (math.sqrt(2 * math.pi) * sigma)
    return finite_result("density", f, "x, mu, sigma")


@dataclass(frozen=True)
class DayNightClassifier:
    """Gaussian naive-Bayes EO/IR classifier: `means` and `sigmas` (2, 3) per class (rows EO,
    IR) and feature (intensity mean, intensity σ, chroma; 8-bit levels), `priors` (2,)."""

    means: np.ndarray
    sigmas: np.ndarray
    priors: np.ndarray

    @classmethod
    def fit(
        cls, eo_frames: Iterable[np.ndarray], ir_frames: Iterable[np.ndarray]
    ) -> DayNightClassifier:
        """Fit the class Gaussians (eq. 2 over each class's frame features) and priors (class
        frequencies) from colour and IR frames (each at least one)."""
        feats = [np.array([frame_features(f) for f in fr]) for fr in (eo_frames, ir_frames)]
        if any(len(f) == 0 for f in feats):
            raise ValueError("eo_frames, ir_frames: each needs at least one frame")
        means = np.array([f.mean(axis=0) for f in feats])
        sigmas = np.maximum(np.array([f.std(axis=0) for f in feats]), MIN_SIGMA)
        counts = np.array([len(f) for f in feats], dtype=float)
        return cls(means, sigmas, counts / counts.sum())

    @classmethod
    def default(cls) -> DayNightClassifier:
        """The shipped classifier: `fit` on the 192 MarDCT training frames (EO) and on grey
        copies of them (IR), rounded to 0.1; equal priors."""
        return cls(
            means=np.array([[151.8, 33.5, 17.8], [151.8, 33.5, 0.0]]),
            sigmas=np.array([[9.0, 4.8, 6.6], [9.0, 4.8, MIN_SIGMA]]),
            priors=np.array([0.5, 0.5]),
        )

    def posteriors(self, image: np.ndarray) -> np.ndarray:
        """(2,) P(θ|F) of EO and IR for a frame (eq. 1), summing to 1."""
        f = frame_features(image)
        # log P(F|θ) + log P(θ), features independent (eq. 3 per feature)
        log_like = np.sum(np.log(gaussian_density(f, self.means, self.sigmas) + 1e-300), axis=1)
        log_post = log_like + np.log(self.priors)
        log_post -= log_post.max()
        p = np.exp(log_post)
        return p / p.sum()

    def classify(self, image: np.ndarray) -> FrameClass:
        """'eo' or 'ir', the class of largest posterior."""
        return CLASSES[int(np.argmax(self.posteriors(image)))]
