"""The valve's input when the rig publishes its valve drive signal.

The identifier takes the valve's input as the rig constants' proportional loop,
``du = K_p (ug - K_f x1)`` (``monitor.identify``). A rig whose controller is anything else (a
PI loop, feed-forward) publishes its drive ``u`` [V] instead; feeding the identifier the
command under which that loop drives the valve with ``u`` gives it ``du = u`` exactly, with no
model of the controller: ``ug' = u / K_p + K_f x1``. The measured x1 enters both and cancels,
so its noise does not reach the valve's input either.
"""

from __future__ import annotations

__all__ = ["command_for_drive"]


def command_for_drive(u, x1, K_p: float, K_f: float):
    """The command [V] for valve drive ``u`` [V] at measured position ``x1`` [m], under
    controller gain ``K_p`` [V/V] and position sensor gain ``K_f`` [V/m]; scalars or arrays.
    Where ``u`` is NaN (not published) the result is NaN too."""
    return u / K_p + K_f * x1
