"""Type stubs of the nsrm package (the native module ``nsrm._nsrm``)."""

import os
import pathlib
from typing import Any, Literal, Optional, Sequence, Tuple, TypedDict, Union, final

import numpy as np
import numpy.typing as npt

__version__: str
__all__ = [
    "GpuUnavailableError",
    "InputError",
    "Model",
    "NsrmError",
    "__version__",
    "builtin_training",
    "delta_e00",
    "eval_loo",
    "export",
    "fit",
    "read_chart",
    "read_frame",
]

_ArrayLike = Union[npt.NDArray[np.float32], npt.NDArray[np.float64], Sequence[Any]]
_PathLike = Union[str, "os.PathLike[str]"]
_White = Union[Sequence[float], str]
_Kind = Literal["lrm", "prm", "rprm", "nsrm", "LRM", "PRM", "RPRM", "NSRM"]

class NsrmError(Exception):
    """The base of every error nsrm raises; its message is the library's."""

class InputError(NsrmError, ValueError):
    """A bad argument or array (wrong shape, dtype, size, or a number out of range)."""

class GpuUnavailableError(NsrmError, RuntimeError):
    """device="gpu" was asked for and no GPU adapter could be opened."""

class _TrainingData(TypedDict):
    labels: list[str]
    camera_rgb: npt.NDArray[np.float64]
    xyz: npt.NDArray[np.float64]
    white_xyz: list[float]
    white_rgb: Optional[list[float]]

class _EvalResult(TypedDict):
    kind: str
    order: int
    terms: int
    mean: float
    median: float
    p95: float
    max: float
    per_patch: npt.NDArray[np.float64]
    labels: list[str]
    f32_unsafe_fits: int

class _ChartReading(TypedDict):
    labels: list[str]
    camera_rgb: npt.NDArray[np.float64]
    xyz: npt.NDArray[np.float64]
    std: npt.NDArray[np.float64]
    count: list[int]
    flags: list[list[str]]
    usable: list[bool]
    white_xyz: list[float]
    corners: npt.NDArray[np.float64]
    report: dict[str, Any]
    csv: str
    training: _TrainingData

class _ExportResult(TypedDict):
    files: list[pathlib.Path]
    max_de00: Optional[float]
    summary: Optional[str]

@final
class Model:
    """A fitted colour-correction model: linear camera RGB → CIE XYZ."""

    @staticmethod
    def load(path: _PathLike) -> "Model":
        """Reads a model file (the JSON ``nsrm fit`` writes)."""
    @staticmethod
    def from_json(text: str, origin: str = "<string>") -> "Model":
        """Parses a model document."""
    def to_json(self) -> str:
        """The model file's JSON text."""
    def save(self, path: _PathLike, overwrite: bool = True) -> None:
        """Writes the model file (the JSON ``nsrm apply`` reads)."""
    @property
    def kind(self) -> str:
        """``"lrm"``, ``"prm"``, ``"rprm"`` or ``"nsrm"``."""
    @property
    def order(self) -> int:
        """The order (LRM: 1)."""
    @property
    def terms(self) -> list[str]:
        """The terms' names, in the order of the matrix's columns."""
    @property
    def matrix(self) -> npt.NDArray[np.float64]:
        """The coefficient matrix, ``(3, L)``: rows X, Y, Z; columns as ``terms``."""
    @property
    def white_xyz(self) -> Tuple[float, float, float]:
        """XYZ of the training white (``apply`` outputs have its Y at 1)."""
    @property
    def input_gains(self) -> Tuple[float, float, float]:
        """Camera RGB gains applied before the terms (1, 1, 1 unless white-balanced)."""
    @property
    def patches(self) -> list[str]:
        """The training patches' labels."""
    @property
    def fit_report(self) -> Optional[dict[str, Any]]:
        """The fit's report (objective, ridge λ, in-sample ΔE00, f32 error, …)."""
    def apply(
        self,
        rgb: _ArrayLike,
        device: Literal["cpu", "gpu"] = "cpu",
        *,
        output_space: Literal["xyz", "linear-srgb", "acescg", "aces2065-1"] = "xyz",
        highlights: Optional[Literal["clip", "keep"]] = None,
        clip_level: Optional[float] = None,
        adapter: Optional[str] = None,
        max_pixels: int = ...,
        out: Optional[npt.NDArray[np.float32]] = None,
    ) -> npt.NDArray[np.float32]:
        """Corrects ``(..., 3)`` or ``(..., 4)`` float32/float64 linear camera RGB (alpha
        untouched) as ``nsrm apply`` does: float32 out, the training white at Y = 1, NaN and Inf
        propagated, nothing clamped. ``device="gpu"`` runs nsrm's wgpu engine
        (``GpuUnavailableError`` without an adapter). A C-contiguous float32 ``rgb`` is read where
        it is (do not modify it from another thread meanwhile); ``out`` (a C-contiguous float32
        array of the same shape, not ``rgb``) receives the result instead of a new array. At most
        ``max_pixels`` pixels (default 268435456, 16384², as ``nsrm apply --max-pixels``)."""
    def apply_f64(self, rgb: _ArrayLike) -> npt.NDArray[np.float64]:
        """The f64 reference, pixel by pixel: XYZ on the training data's scale (not divided by
        the white's Y)."""

def fit(
    camera_rgb: _ArrayLike,
    xyz: _ArrayLike,
    kind: _Kind = "nsrm",
    order: int = 3,
    *,
    objective: str = "ls",
    preserve_white: bool = False,
    ridge: Union[None, float, str] = None,
    white: Optional[_White] = None,
    white_patch: Optional[str] = None,
    white_rgb: Optional[Sequence[float]] = None,
    normalise: Literal["raw", "white-balanced"] = "raw",
    labels: Optional[Sequence[str]] = None,
) -> Model:
    """Fits a model on ``(N, 3)`` camera RGB → XYZ as ``nsrm fit`` does. ``white`` (required) is
    the white the XYZ are relative to: ``(X, Y, Z)``, ``"x,y"`` or an illuminant name."""

def eval_loo(
    camera_rgb: _ArrayLike,
    xyz: _ArrayLike,
    kind: _Kind = "nsrm",
    order: int = 3,
    *,
    white: Optional[_White] = None,
    objective: str = "ls",
    preserve_white: bool = False,
    ridge: Union[None, float, str] = None,
    white_patch: Optional[str] = None,
    white_rgb: Optional[Sequence[float]] = None,
    normalise: Literal["raw", "white-balanced"] = "raw",
    labels: Optional[Sequence[str]] = None,
    in_sample: bool = False,
    f32_guard: bool = False,
) -> _EvalResult:
    """Leave-one-out ΔE00 per patch and its statistics, as ``nsrm eval``."""

def delta_e00(lab1: _ArrayLike, lab2: _ArrayLike) -> npt.NDArray[np.float64]:
    """CIEDE2000 (kL = kC = kH = 1) between two ``(..., 3)`` Lab arrays, broadcast together as
    numpy does; float64 of the broadcast shape without its last axis."""

def builtin_training(
    camera: str = "nikon-d5100",
    illuminant: str = "D65",
    chart: str = "cc24",
    *,
    patches: str = "all",
) -> _TrainingData:
    """A training set simulated from the built-in spectra (or CSV files of the same columns):
    camera sensitivities × illuminant × reflectances (``chart``: ``cc24``, ``rawtoaces-190`` or a
    file); ``patches`` selects as ``nsrm eval --patches`` (``all``, ``A1,C3``, ``B2:M9``)."""

def read_chart(
    path: Union[_PathLike, npt.NDArray[np.float32], npt.NDArray[np.float64]],
    chart: Literal["cc24", "sg"] = "cc24",
    *,
    reference: Optional[str] = None,
    reference_white: Optional[_White] = None,
    corners: Union[None, str, Sequence[Sequence[float]]] = None,
    white_level: Optional[float] = None,
    flat: Optional[str] = None,
    encoding: Literal["auto", "linear", "srgb"] = "auto",
    demosaic: Literal["half", "bilinear", "mhc"] = "half",
    layer: Optional[str] = None,
    max_pixels: int = ...,
) -> _ChartReading:
    """Reads the chart in a photograph as ``nsrm chart extract`` does: a file, or an
    ``(height, width, 3 | 4)`` array of linear camera RGB (read as a linear file is)."""

def read_frame(
    path: _PathLike,
    *,
    demosaic: Literal["half", "bilinear", "mhc"] = "mhc",
    layer: Optional[str] = None,
    max_pixels: int = ...,
) -> npt.NDArray[np.float32]:
    """Decodes a linear EXR / TIFF or a camera raw file as ``nsrm apply`` does:
    ``(height, width, 3)`` float32 camera RGB."""

def export(
    model: Model,
    format: Literal[
        "clf", "cube", "ocio", "dcp", "icc", "dctl", "wgsl", "glsl", "hlsl", "msl", "spirv"
    ],
    path: _PathLike,
    *,
    output_space: Literal["xyz", "linear-srgb", "acescg", "aces2065-1"] = "xyz",
    lut_size: int = 65,
    shaper_size: int = 65536,
    stops: Optional[Tuple[float, float]] = None,
    interpolation: Literal["tetrahedral", "trilinear"] = "tetrahedral",
    dcp_map: Tuple[int, int] = ...,
    max_de00: Optional[float] = None,
    training_rgb: Optional[_ArrayLike] = None,
    overwrite: bool = True,
    layout: Literal["rgb", "rgba"] = "rgb",
) -> _ExportResult:
    """Writes the model as a CLF, .cube, OCIO config, DCP or ICC profile with its measured error,
    as ``nsrm export`` (``training_rgb``: the patches to measure it on; default: those it was
    fitted on, or re-simulated from a model file's provenance); or as a DCTL or a compute shader
    (``layout``), the model exactly, as ``nsrm export-shader``."""
