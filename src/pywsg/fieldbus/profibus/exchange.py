"""``profibus://PORT?address=7&baudrate=19200``: the PLC side's :class:`~pywsg.fieldbus.exchange.ImageExchange`
over PROFIBUS DP, for :func:`pywsg.fieldbus.exchange.open_exchange` (see :mod:`.master`)."""

from __future__ import annotations

from .master import ProfibusError, ProfibusExchange, ProfibusUrl


async def open_exchange(url: str, *, timeout: float = 3.0) -> ProfibusExchange:
    """Open a DP master on the URL's port; ValueError for a malformed URL, :class:`ProfibusError`
    (a ConnectionError) when pyprofibus is missing or the slave does not reach Data_Exch."""
    return await ProfibusExchange.open(ProfibusUrl.parse(url), timeout=max(timeout, 1.0))


__all__ = ["ProfibusError", "ProfibusExchange", "open_exchange"]
