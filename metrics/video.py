"""A perceptual score for frame sequences: ColorVideoVDP (Mantiuk et al., SIGGRAPH 2024), the
``cvvdp`` package on PyPI (PyTorch), as the optional extra ``raster-oracle[video]``.

Arrays in, numbers out: :func:`cvvdp_jod` takes the tone-mapped, sRGB-encoded frames of a
candidate and its reference (``(T, H, W, 3)`` in [0, 1], the images a display shows) and
returns ColorVideoVDP's quality in JOD (just-objectionable differences: 10 = identical; one
JOD less = 75 % of observers prefer the other sequence). The display is the package's SDR
``standard_fhd`` photometry (sRGB, 200 cd/m^2 peak) seen at the score's pixels per degree,
the sequence at 30 frames per second (or as given). Torch and cvvdp are imported on the
first call only; :func:`unavailable` says, in one line, why the score cannot run.

Works offline: the package ships its display, colour-space and CSF files
(``pycvvdp/vvdp_data``); it downloads only for its ML variants, which are not used. PyPI's
``torchvision`` wheels are CUDA builds whose C extension does not load next to PyTorch's
CPU build (``import torchvision`` fails on ``torchvision::nms``); cvvdp needs from it only
``transforms.GaussianBlur`` (and imports ``ops.MLP`` for the unused ML metrics). Where that
import fails, :func:`_torchvision_standin` provides the blur as torchvision 0.28 defines it
(``_functional_tensor.gaussian_blur``: a normalised sampled Gaussian of the given size,
reflect padding, a depthwise 2-D convolution), so the score is the package's own.

References
----------
R. K. Mantiuk, P. Hanji, M. Ashraf, Y. Asano, A. Chapiro, ColorVideoVDP: A visual difference
predictor for image, video and display distortions, ACM TOG 43(4) (SIGGRAPH 2024),
doi:10.1145/3658144.
"""

from __future__ import annotations

import sys
import types

import numpy as np

__all__ = ["DISPLAY", "FPS", "cvvdp_jod", "unavailable"]

#: The display photometry the sequences are judged on (SDR sRGB, cvvdp's ``standard_fhd``).
DISPLAY = "standard_fhd"
#: Frames per second of a scored sequence.
FPS = 30.0
#: One line for a run without the extra.
MISSING = "cvvdp_jod skipped: ColorVideoVDP is not installed (pip install raster-oracle[video])"

_METRICS: dict = {}


def unavailable() -> str | None:
    """None when ColorVideoVDP can run, else one line saying why not."""
    try:
        _load()
    except ImportError:
        return MISSING
    return None


def _torchvision_standin() -> None:
    """Put a ``torchvision`` with ``transforms.GaussianBlur`` (as torchvision defines it)
    and ``ops.MLP`` (unusable: the ML metrics are not used) into ``sys.modules``."""
    import torch
    import torch.nn.functional as F

    class GaussianBlur(torch.nn.Module):
        def __init__(self, kernel_size, sigma=(0.1, 2.0)):
            super().__init__()
            self.k = int(kernel_size)
            self.sigma = float(sigma if np.isscalar(sigma) else sigma[0])

        def forward(self, img):
            half = (self.k - 1) * 0.5
            x = torch.linspace(-half, half, steps=self.k, dtype=img.dtype, device=img.device)
            pdf = torch.exp(-0.5 * (x / self.sigma).pow(2))
            k1 = pdf / pdf.sum()
            k2 = torch.mm(k1[:, None], k1[None, :])
            shape = img.shape
            flat = img.reshape(-1, *shape[-3:])
            kernel = k2.expand(shape[-3], 1, self.k, self.k)
            pad = [self.k // 2] * 4
            out = F.conv2d(F.pad(flat, pad, mode="reflect"), kernel, groups=shape[-3])
            return out.reshape(shape)

    class MLP:
        def __init__(self, *args, **kwargs):
            raise ImportError("torchvision.ops.MLP is not available (CPU PyTorch)")

    tv = types.ModuleType("torchvision")
    tv.transforms = types.ModuleType("torchvision.transforms")
    tv.ops = types.ModuleType("torchvision.ops")
    tv.transforms.GaussianBlur = GaussianBlur
    tv.ops.MLP = MLP
    sys.modules.update(
        {"torchvision": tv, "torchvision.transforms": tv.transforms, "torchvision.ops": tv.ops}
    )


def _load():
    """``(torch, pycvvdp)``, importing them once; ImportError when either is missing."""
    if "modules" in _METRICS:
        return _METRICS["modules"]
    import torch

    try:
        import torchvision  # noqa: F401
    except (ImportError, RuntimeError):
        for name in [n for n in sys.modules if n.split(".")[0] == "torchvision"]:
            del sys.modules[name]
        _torchvision_standin()
    import pycvvdp

    _METRICS["modules"] = (torch, pycvvdp)
    return _METRICS["modules"]


def cvvdp_jod(
    reference: np.ndarray, candidate: np.ndarray, *, ppd: float, fps: float = FPS
) -> float:
    """ColorVideoVDP's JOD of ``candidate`` against ``reference``.

    Parameters
    ----------
    reference, candidate : (T, H, W, 3) display-encoded (sRGB) frames in [0, 1] (T >= 1; one
        frame is judged as an image).
    ppd : pixels per degree of visual angle the frames are seen at.
    fps : frames per second of the sequence.

    Returns
    -------
    float: JOD, 10 for identical sequences, lower is worse.

    Raises
    ------
    ImportError
        The extra is not installed (see :func:`unavailable`).
    ValueError
        The arrays' shapes differ or are not (T, H, W, 3) with H, W >= 2 (ColorVideoVDP's
        pyramid fails on one pixel).
    """
    ref = np.asarray(reference, np.float32)
    cand = np.asarray(candidate, np.float32)
    if ref.shape != cand.shape or ref.ndim != 4 or ref.shape[-1] != 3 or min(ref.shape[1:3]) < 2:
        raise ValueError(f"cvvdp_jod: frames must be two (T, H, W, 3) arrays of at least 2x2 "
                         f"pixels, got {ref.shape} and {cand.shape}")  # fmt: skip
    torch, pycvvdp = _load()
    key = (float(ppd), ref.shape[1], ref.shape[2])
    if key not in _METRICS:
        h, w = ref.shape[1:3]
        geometry = pycvvdp.vvdp_display_geometry((w, h), ppd=float(ppd))
        _METRICS[key] = pycvvdp.cvvdp(
            display_name=DISPLAY,
            display_geometry=geometry,
            device=torch.device("cpu"),
            quiet=True,
        )
    metric = _METRICS[key]
    fps_arg = float(fps) if ref.shape[0] > 1 else 0
    with torch.no_grad():
        q, _ = metric.predict(
            np.clip(cand, 0.0, 1.0),
            np.clip(ref, 0.0, 1.0),
            dim_order="FHWC",
            frames_per_second=fps_arg,
        )
    return float(q)
