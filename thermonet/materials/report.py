"""The effective properties of a net built from continuum materials, measured on the net, and
their lines in ``thermonet info``."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..kernels.springs import map_springs
from .homogenize import Conductive, Elastic, conductivity_tensor, elastic_tensor


class Effective(NamedTuple):
    """elastic: :class:`Elastic`; conduction: :class:`Conductive` or None (no conductance);
    mass: Σ node masses; heat_capacity: Σ C_e at rest and θ0; volume: Σ V_e."""

    elastic: Elastic
    conduction: Conductive | None
    mass: float
    heat_capacity: float
    volume: float


def spring_rest_values(model, P: np.ndarray, l0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(stiffness d²F/dl², heat capacity −θ ∂²F/∂θ²), each (m,), at rest and θ0, from the model's
    own functions and the (k, m) parameters P."""
    theta0 = np.ascontiguousarray(P[model.parameters.index(model.reference_temperature)])
    l0 = np.ascontiguousarray(l0, dtype=np.float64)
    P = np.ascontiguousarray(P, dtype=np.float64)
    k, F_tt = np.empty(len(l0)), np.empty(len(l0))
    map_springs(model, "d2F_dl2")(l0, theta0, l0, P, k)
    map_springs(model, "d2F_dtheta2")(l0, theta0, l0, P, F_tt)
    return k, -theta0 * F_tt


def measure(net, model, parameters: dict, volume: np.ndarray, boundary: np.ndarray, d: int) -> Effective:
    """The net's effective properties. parameters: name -> (m,) (model and transport ones);
    volume: (m,) V_e of the springs; boundary: (n,) nodes held to the uniform fields."""
    P = model.parameter_array({k: v for k, v in parameters.items() if k in model.parameters}, net.n_springs)
    k, C = spring_rest_values(model, P, net.rest_lengths)
    V = float(np.nansum(volume))
    elastic = elastic_tensor(net.positions, net.edges, k, V, boundary, d)
    g = np.asarray(parameters.get("g", 0.0), dtype=np.float64) * np.ones(net.n_springs)
    conduction = conductivity_tensor(net, g, V, boundary, d) if (g > 0).any() else None
    return Effective(elastic, conduction, float(net.masses.sum()), float(C.sum()), V)


def describe(eff: Effective, given: dict, d: int, junction_factor: float = 1.0) -> list[str]:
    """Lines of ``thermonet info``: measured values beside the volume-weighted given ones.
    given: volume-weighted means of the continuum properties (name -> float);
    junction_factor: what the conductances were scaled by."""
    el = eff.elastic
    frame = {3: "x, y, z", 2: "the in-plane principal axes", 1: "the line"}[d]
    nu_rule = {3: "1/4", 2: "1/3"}.get(d)
    out = [f"  continuum: effective properties measured on the net ({d}D, volume {eff.volume:.6g}; uniform "
           "fields on the boundary, interior relaxed)"]
    E = given.get("youngs_modulus")
    text = f"    Young's modulus {el.E:.4g}" + (f" (given {E:.4g}, ratio {el.E / E:.4f})" if E else "")
    if d > 1:
        text += f"; Poisson's ratio {el.nu:.4f} (a central-force net: {nu_rule})"
    out.append(text)
    if d > 1:
        out.append(f"    along {frame}: E = " + ", ".join(f"{e:.4g}" for e in el.E_axes)
                   + f"; anisotropy ‖C − C_iso‖/‖C‖ = {el.anisotropy:.3f}")
    if eff.conduction is not None:
        c = eff.conduction
        k = given.get("conductivity")
        out.append(f"    conductivity {c.k:.4g}" + (f" (given {k:.4g}, ratio {c.k / k:.4f})" if k else "")
                   + (f"; anisotropy (max − min)/mean = {c.anisotropy:.3f}" if d > 1 else "")
                   + (f"; conductances × {junction_factor:.4f} (junction factor)" if junction_factor != 1.0 else ""))
    rho, cv = given.get("density"), given.get("heat_capacity")
    out.append(f"    mass {eff.mass:.6g}" + (f" (ρ V = {rho * eff.volume:.6g})" if rho else "")
               + f"; heat capacity {eff.heat_capacity:.6g}" + (f" (c_v V = {cv * eff.volume:.6g})" if cv else ""))
    return out
