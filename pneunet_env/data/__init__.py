"""Packaged data files: the real-object catalogue (``objects.yaml``), read by :mod:`pneunet_env.catalogue`."""
