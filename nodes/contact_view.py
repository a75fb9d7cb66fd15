"""The slip tests' view of a ``contact`` message: it lives in ``lib/contact_view.py``
(the library detector needs it without the nodes); re-exported for the nodes."""

from slipstack.lib.contact_view import ContactView, pad_positions

__all__ = ["ContactView", "pad_positions"]
