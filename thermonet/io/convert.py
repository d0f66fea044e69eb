"""A net, or a simulation's current state, as a meshio mesh or a PyVista grid: springs as line
cells, in the user's numbering (for plotting in a notebook, or writing any format meshio knows).

The fields are those of the output frames (:data:`thermonet.io.series.FIELDS`) where they exist:
for a net, node masses, the anchored flag and spring rest lengths; for a simulation, the current
positions, displacement, velocity and momentum per node and temperature, entropy, strain and
tension per spring (thermal ones only with thermal coupling).
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError


def net_mesh(net):
    """``meshio.Mesh`` of a :class:`~thermonet.net.Net`: points (n, 3) = initial positions, one
    "line" cell block (m, 2) = springs; point data ``mass`` (n,), ``anchored`` (n,) uint8; cell
    data ``rest_length`` (m,)."""
    return _mesh(net.positions, net.edges, {"mass": net.masses, "anchored": net.anchored.astype(np.uint8)},
                 {"rest_length": net.rest_lengths})


def simulation_mesh(sim):
    """``meshio.Mesh`` of a simulation's current state (user numbering): points (n, 3) = current
    positions, "line" cells (m, 2); point data ``displacement``, ``velocity``, ``momentum`` (n, 3)
    and ``anchored`` (n,); cell data ``strain``, ``tension`` (m,) and, with thermal coupling,
    ``temperature`` and ``entropy`` (m,) and point data ``node_temperature`` (n,), the frames'
    (with conduction the junction temperatures), and with conduction cell data ``heat_rate``
    (m,), each spring's net heat inflow."""
    net, state = sim.net, sim.state
    points = {"displacement": state.positions - net.positions, "velocity": state.momenta / net.masses[:, None],
              "momentum": state.momenta, "anchored": net.anchored.astype(np.uint8)}
    points["velocity"][net.anchored] = 0.0
    fields = sim.spring_fields()
    cells = {"strain": sim.strains(), "tension": fields.tension}
    if sim.system.thermal:
        cells.update(temperature=fields.temperature, entropy=state.entropy)
        # the frames' node temperature (junction temperatures with conduction) and heat inflow
        heat = sim.system.heat
        extra_points = {"node_temperature": np.empty(net.n_nodes)}
        extra_cells = {"heat_rate": np.empty(net.n_springs)} if heat is not None and heat.conduction else {}
        sim.output_fields(np.empty((net.n_nodes, 3)), extra_points, extra_cells).write()
        points.update(extra_points)
        cells.update(extra_cells)
    return _mesh(state.positions, net.edges, points, cells)


def _mesh(points, edges, point_data: dict, cell_data: dict):
    import meshio

    return meshio.Mesh(np.asarray(points, dtype=np.float64), [("line", np.asarray(edges, dtype=np.int64))],
                       point_data={k: np.asarray(v) for k, v in point_data.items()},
                       cell_data={k: [np.asarray(v)] for k, v in cell_data.items()})


def to_pyvista(mesh):
    """A ``pyvista.UnstructuredGrid`` of a meshio mesh from :func:`net_mesh` or
    :func:`simulation_mesh` (PyVista imported here: an optional dependency, ``pip install
    'thermonet[vis]'``)."""
    try:
        import pyvista as pv
    except ImportError:
        raise InputError("to_pyvista needs PyVista: pip install 'thermonet[vis]'") from None
    return pv.from_meshio(mesh)
