"""The PROFIBUS GSD package's device icons (003 §2.1: ``WSG_D.bmp``, ``WSG_R.bmp``, ``WSG_S.bmp``), drawn here.

A configuration tool shows one of three icons per slave, named in the GSD by ``Bitmap_Device`` (normal
operation, "run": ``WSG_R``), ``Bitmap_Diag`` (diagnosis: ``WSG_D``) and ``Bitmap_SF`` (special function,
"stop": ``WSG_S``). The GSD convention: Windows BMP, 70 × 40 pixels, 16 colours. The manuals list the files
but show no picture, so these are pywsg's own drawing: a gripper (body and two fingers) with a status badge —
green dot (run), red "!" (diagnosis), yellow bar (stop).

``python -m pywsg.fieldbus.descriptions.bitmaps DIR`` writes them; the package data are this function's
output (a test checks they match).
"""

from __future__ import annotations

import struct
import sys
from pathlib import Path

WIDTH, HEIGHT = 70, 40
#: The 16-colour VGA palette (index: RGB).
PALETTE = ((0, 0, 0), (128, 0, 0), (0, 128, 0), (128, 128, 0), (0, 0, 128), (128, 0, 128), (0, 128, 128),
           (192, 192, 192), (128, 128, 128), (255, 0, 0), (0, 255, 0), (255, 255, 0), (0, 0, 255),
           (255, 0, 255), (0, 255, 255), (255, 255, 255))
BLACK, DARK_GREEN, GREY, LIGHT_GREY, RED, GREEN, YELLOW, WHITE = 0, 2, 8, 7, 9, 10, 11, 15
NAMES = {"WSG_R.bmp": "run", "WSG_D.bmp": "diagnosis", "WSG_S.bmp": "stop"}

Pixels = list[list[int]]


def _rect(px: Pixels, x0: int, y0: int, x1: int, y1: int, colour: int) -> None:
    """Fill x0..x1-1, y0..y1-1 (y down)."""
    for y in range(max(0, y0), min(HEIGHT, y1)):
        for x in range(max(0, x0), min(WIDTH, x1)):
            px[y][x] = colour


def _disc(px: Pixels, cx: int, cy: int, r: int, colour: int) -> None:
    for y in range(cy - r, cy + r + 1):
        for x in range(cx - r, cx + r + 1):
            if (x - cx) ** 2 + (y - cy) ** 2 <= r * r and 0 <= x < WIDTH and 0 <= y < HEIGHT:
                px[y][x] = colour


def draw(state: str) -> Pixels:
    """The icon for ``state`` ("run", "diagnosis", "stop") as rows of palette indices, top row first."""
    px = [[WHITE] * WIDTH for _ in range(HEIGHT)]
    _rect(px, 0, 0, WIDTH, 1, GREY)                 # frame
    _rect(px, 0, HEIGHT - 1, WIDTH, HEIGHT, GREY)
    _rect(px, 0, 0, 1, HEIGHT, GREY)
    _rect(px, WIDTH - 1, 0, WIDTH, HEIGHT, GREY)
    _rect(px, 8, 4, 44, 18, GREY)                   # gripper body
    _rect(px, 10, 6, 42, 16, LIGHT_GREY)
    _rect(px, 14, 8, 38, 10, BLACK)                 # guide rail
    _rect(px, 12, 18, 18, 34, GREY)                 # fingers
    _rect(px, 34, 18, 40, 34, GREY)
    _rect(px, 18, 28, 22, 34, GREY)                 # finger tips, facing each other
    _rect(px, 30, 28, 34, 34, GREY)
    if state == "run":
        _disc(px, 57, 26, 8, DARK_GREEN)
        _disc(px, 57, 26, 6, GREEN)
    elif state == "diagnosis":
        _disc(px, 57, 26, 8, RED)
        _rect(px, 56, 20, 59, 28, WHITE)            # "!"
        _rect(px, 56, 30, 59, 33, WHITE)
    else:
        _rect(px, 49, 18, 66, 35, BLACK)
        _rect(px, 50, 19, 65, 34, YELLOW)
        _rect(px, 52, 25, 63, 28, BLACK)            # "–": stopped
    return px


def bmp(px: Pixels) -> bytes:
    """A 4-bit (16-colour) Windows BMP, rows bottom-up and padded to 4 bytes."""
    row_bytes = (WIDTH * 4 + 31) // 32 * 4
    rows = b""
    for row in reversed(px):
        packed = bytes((row[x] << 4) | (row[x + 1] if x + 1 < WIDTH else 0) for x in range(0, WIDTH, 2))
        rows += packed.ljust(row_bytes, b"\0")
    palette = b"".join(bytes((b_, g, r, 0)) for r, g, b_ in PALETTE)
    offset = 14 + 40 + len(palette)
    info = struct.pack("<IiiHHIIiiII", 40, WIDTH, HEIGHT, 1, 4, 0, len(rows), 2835, 2835, 16, 16)
    return struct.pack("<2sIHHI", b"BM", offset + len(rows), 0, 0, offset) + info + palette + rows


def icons() -> dict[str, bytes]:
    """File name → BMP bytes of the three icons."""
    return {name: bmp(draw(state)) for name, state in NAMES.items()}


def main(argv: list[str]) -> None:
    folder = Path(argv[0] if argv else ".")
    for name, data in icons().items():
        (folder / name).write_bytes(data)
        print(folder / name)


if __name__ == "__main__":
    main(sys.argv[1:])
