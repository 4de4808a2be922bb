"""Temporal anti-aliasing (``taa``): jitter, current-frame filter, history sampling,
reprojection with the model's own motion vectors, neighbourhood rectification, history blend
and rejection; the engine presets are transcriptions of the engines' shipped shaders.

Engine resolves (one frame each, vectorized; sources pinned in their docstrings):
:mod:`.ue4` (UE 4.19 main pass), :mod:`.inside` (playdeadgames/temporal), :mod:`.hdrp` (Unity
HDRP, TAAQuality Medium and High), :mod:`.filament` (Filament ``taa.mat``), with
:mod:`.hardware` (8-bit sRGB, half-float and R11G11B10 storage, the 5-tap Catmull-Rom).
The part-by-part pipeline: :mod:`.jitter` (Halton 2,3, UE4's Gaussian mapping),
:mod:`.filters` (3x3 ``exp(-2.29 d^2)`` or box; bilinear or Catmull-Rom history),
:mod:`.rectify` (clamp, AABB clip, variance clip; RGB or YCoCg; 3x3, plus, rounded),
:mod:`.blend` (constant, UE4 luma-contrast, INSIDE feedback), :mod:`.params` (parameters and
presets with their sources), :mod:`.model` (the frame loop and the cost record).

References
----------
B. Karis, High Quality Temporal Supersampling, SIGGRAPH 2014 Advances in Real-Time Rendering.
L. J. F. Pedersen, Temporal Reprojection Anti-Aliasing in INSIDE, GDC 2016.
M. Salvi, An Excursion in Temporal Supersampling, GDC 2016.
L. Yang, S. Liu, M. Salvi, A Survey of Temporal Antialiasing Techniques, CGF 39(2) 2020,
doi:10.1111/cgf.14018.
"""

from .model import run
from .params import PRESETS, TaaParams

__all__ = ["PRESETS", "TaaParams", "run"]
