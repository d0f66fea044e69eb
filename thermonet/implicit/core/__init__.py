"""The core every implicit scheme shares (see :mod:`thermonet.implicit`)."""
