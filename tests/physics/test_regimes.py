"""The regime of an object (force- or position-controlled) from the mechanics, consistent with the paper's ring."""

from __future__ import annotations

import numpy as np

from pneunet_env.physics.regimes import FORCE, POSITION, UNREACHABLE, blocked_fraction, regime


def test_the_papers_boundaries_on_its_ring():
    # README statement 10: force-controlled below k~ = 4.47e-4, position-controlled from 1.12e-3, at p~ = 1.2
    phi = blocked_fraction([4.47e-4, 1.12e-3], 0.02)
    assert phi[0] < 0.01 and phi[1] > 0.99
    assert list(regime([1e-5, 4.47e-4, 1.12e-3, 1e-1], 0.02)) == [FORCE, FORCE, POSITION, POSITION]


def test_a_hand_scale_object_needs_a_stiffer_contact_to_block():
    # the same k~ blocks the ring but not a 20 mm object: the regime is not a threshold on k~ alone
    k = 3e-3
    assert regime(k, 0.02)[0] == POSITION and regime(k, 0.25)[0] == FORCE
    phi = blocked_fraction(np.logspace(-3, 2, 11), 0.25)
    assert np.all(np.diff(phi) >= -1e-12) and phi[0] < 0.05 and phi[-1] > 0.95  # monotone in k~, 0 to 1


def test_objects_beyond_the_free_reach_are_unreachable():
    assert regime(1.0, 0.6)[0] == UNREACHABLE and np.isnan(blocked_fraction(1.0, 0.6)[0])
