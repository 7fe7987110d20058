"""Typed stubs of npf's compiled core (python/src/lib.rs)."""

from os import PathLike
from typing import Any, Callable, Dict, List, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

_Path = Union[str, "PathLike[str]"]
_Floats = npt.ArrayLike  # float32/float64 array (N, 3) or (3,)
_F64 = npt.NDArray[np.float64]

EXPORT_FORMATS: List[str]
__version__: str

class Model:
    """A fitted npf model: factor tables, provenance, evaluator and sampler."""

    @property
    def num_parameters(self) -> int: ...
    @property
    def lobes(self) -> int: ...
    @property
    def isotropic(self) -> bool: ...
    @property
    def d(self) -> _F64:
        """Lambertian term d_C (1/sr), shape (3,), read-only."""
    @property
    def s(self) -> _F64:
        """Scales s_C^m, shape (lobes, 3), read-only."""
    @property
    def F(self) -> _F64:
        """Fresnel F_C(theta_d), shape (3, n_F), read-only."""
    @property
    def D(self) -> _F64:
        """D^m(theta_h), shape (lobes, n_D) or (lobes, n_theta, n_phi), read-only."""
    @property
    def G(self) -> _F64:
        """G^m(theta) control points, shape (lobes, n_G) or (lobes, n_theta, n_phi)."""
    @property
    def axes(self) -> Dict[str, Dict[str, Any]]:
        """Per factor ("D", "F", "G"): name, kind, theta nodes (rad)[, phi nodes]."""
    @property
    def fit_info(self) -> Optional[Dict[str, Any]]: ...
    def eval(self, wi: _Floats, wo: _Floats) -> _F64:
        """BRDF (1/sr), (N, 3); wi towards the light, wo towards the viewer."""
    def sample(self, wo: _Floats, u: _Floats) -> Tuple[_F64, Union[_F64, float], _F64]:
        """(wi (N, 3), pdf (N,), weight (N, 3) = f cos / pdf); u (N, 2) or (N, 3)."""
    def pdf(self, wo: _Floats, wi: _Floats) -> Union[_F64, float]:
        """Density of sample's wi per solid angle, (N,)."""
    def albedo(self, wo: _Floats) -> _F64:
        """Directional albedo (N, 3) by quadrature."""
    def reconstruct(self) -> _F64:
        """The model as a MERL table, (3, 90, 90, 180), 1/sr, negative = missing."""
    def save(self, path: _Path, overwrite: bool = False) -> None: ...
    def export(self, path: _Path, overwrite: bool = False) -> None: ...
    def _eval1(
        self, wi: Tuple[float, float, float], wo: Tuple[float, float, float]
    ) -> Tuple[float, float, float]: ...
    def _pdf1(self, wo: Tuple[float, float, float], wi: Tuple[float, float, float]) -> float: ...
    def _sample1(
        self, wo: Tuple[float, float, float], u: Tuple[float, float, float]
    ) -> Tuple[Tuple[float, float, float], float, Tuple[float, float, float]]: ...

    def _kernel_seconds(
        self, wi: _Floats, wo: _Floats, u: _Floats
    ) -> Tuple[float, float, float]: ...

def load(path: _Path) -> Model: ...
def from_json(text: str) -> Model: ...
def read_merl(path: _Path, raw: bool = False) -> _F64: ...
def write_merl(path: _Path, table: npt.ArrayLike, raw: bool = False, overwrite: bool = False) -> None: ...
def fit(
    table_or_path: Union[_Path, npt.ArrayLike],
    lobes: int = 3,
    weighting: str = "compressive",
    *,
    model: str = "factor",
    nodes: int = 90,
    epsilon: Optional[float] = None,
    max_theta: Optional[float] = None,
    max_theta_h: Optional[float] = None,
    max_sweeps: Optional[int] = None,
    tol: Optional[float] = None,
    g_method: Optional[str] = None,
    smooth_g: Optional[float] = None,
    d_monotone_from: Optional[float] = None,
    accelerate: Optional[bool] = None,
    energy_scale: Optional[bool] = None,
    threads: int = 0,
    progress: Optional[Callable[[Dict[str, Any]], Any]] = None,
    diffuse: str = "lambert",
) -> Model: ...
