"""The ghost layer's positions, exchanged with the neighbouring processes once per stage.

Non-blocking point-to-point messages (``Irecv``/``Isend`` into preallocated buffers): every
receive is posted before any send, so no ordering between processes can deadlock.
"""

from __future__ import annotations

import numpy as np

#: message tag of the position halo
TAG = 33


class Halo:
    """Sends the positions of owned nodes that are ghosts elsewhere and receives the ghosts'.

    comm: the mpi4py communicator; send, recv: neighbour rank -> (k,) local node indices
    (:class:`~thermonet.parallel.domain.Share`). Counts ``messages`` and ``bytes`` sent.
    """

    def __init__(self, comm, send: dict, recv: dict):
        self.comm = comm
        self._send = [(q, idx, np.empty((len(idx), 3))) for q, idx in sorted(send.items())]
        self._recv = [(q, idx, np.empty((len(idx), 3))) for q, idx in sorted(recv.items())]
        self.messages = 0
        self.bytes = 0

    @property
    def bytes_per_exchange(self) -> int:
        """Bytes this process sends in one exchange."""
        return sum(buf.nbytes for _, _, buf in self._send)

    def exchange(self, x: np.ndarray) -> None:
        """Overwrite the ghost rows of ``x`` (nl, 3) with their owners' values."""
        from mpi4py import MPI

        requests = [self.comm.Irecv(buf, source=q, tag=TAG) for q, _, buf in self._recv]
        for q, idx, buf in self._send:
            np.take(x, idx, axis=0, out=buf)
            requests.append(self.comm.Isend(buf, dest=q, tag=TAG))
        MPI.Request.Waitall(requests)
        for _, idx, buf in self._recv:
            x[idx] = buf
        self.messages += len(self._send)
        self.bytes += self.bytes_per_exchange
