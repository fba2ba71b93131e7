"""``contact.png``: every variant of a batch side by side, as a photographer's contact sheet.

Each tile is a variant's ``preview.png`` shrunk to a common width, with its
id and key figures printed beneath (a grey tile where a variant has no
preview).  Tiles run left to right, top to bottom, in the batch's order, in
a near-square grid, saved with a 256-colour palette.  The same previews and
captions give the same bytes.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

from PIL import Image, ImageDraw, ImageFont

__all__ = ["contact_sheet", "MAX_TILES"]

MAX_TILES = 1024  # a larger batch shows its first 1,024 variants
_BACKGROUND = (255, 255, 255)
_EMPTY = (225, 225, 222)
_INK = (30, 30, 30)
_GREY = (110, 110, 110)


def _font(size: int) -> ImageFont.ImageFont:
    try:
        return ImageFont.load_default(size=size)  # Pillow >= 10.1 with FreeType
    except (TypeError, ValueError, OSError, ImportError):
        return ImageFont.load_default()


def contact_sheet(
    tiles: Sequence[tuple[Path | None, str, str]],
    path: Path,
    *,
    max_width: int = 4800,
    tile_width: int = 360,
) -> Path:
    """Draw ``tiles`` into a PNG at ``path``.

    Parameters
    ----------
    tiles : sequence of (preview path or None, title, caption)
        One per variant, in order; the title (its id) is printed in black
        and the caption (its key figures) in grey beneath the picture.
    path : path
        The PNG to write (replaced).
    max_width : int
        Widest sheet (px); tiles shrink down to 120 px to fit it.
    tile_width : int
        Width of a tile (px) when the sheet is not wider than ``max_width``.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    tiles = list(tiles)[:MAX_TILES]
    n = max(1, len(tiles))
    cols = math.ceil(math.sqrt(n))
    rows = math.ceil(n / cols)
    pad = 8
    width = max(120, min(tile_width, (max_width - pad) // cols - pad))
    pictures = []
    for preview, _, _ in tiles:
        im = None
        if preview is not None and Path(preview).is_file():
            with Image.open(preview) as src:
                src = src.convert("RGB")
                h = max(1, round(src.height * width / src.width))
                im = src.resize((width, h), Image.Resampling.LANCZOS, reducing_gap=3.0)
        pictures.append(im)
    pic_h = max((im.height for im in pictures if im is not None), default=round(width * 0.7))
    size = max(10, width // 24)
    title_font, caption_font = _font(size + 2), _font(size)
    text_h = 2 * (size + 6) + 4
    cell_w, cell_h = width + pad, pic_h + text_h + pad
    sheet = Image.new("RGB", (cols * cell_w + pad, rows * cell_h + pad), _BACKGROUND)
    draw = ImageDraw.Draw(sheet)
    for k, ((_, title, caption), im) in enumerate(zip(tiles, pictures)):
        x = pad + (k % cols) * cell_w
        y = pad + (k // cols) * cell_h
        if im is None:
            draw.rectangle((x, y, x + width - 1, y + pic_h - 1), fill=_EMPTY)
            draw.text((x + 6, y + 6), "no preview", fill=_GREY, font=caption_font)
        else:
            sheet.paste(im, (x, y))
        draw.text((x, y + pic_h + 3), _fit(draw, title, title_font, width), fill=_INK, font=title_font)
        draw.text((x, y + pic_h + size + 9), _fit(draw, caption, caption_font, width), fill=_GREY, font=caption_font)
    path = Path(path)
    # 256 colours (fast octree, no dithering): a third of the RGB file, and the same bytes for the same tiles
    sheet.quantize(colors=256, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE).save(path, format="PNG")
    return path


def _fit(draw: ImageDraw.ImageDraw, text: str, font, width: int) -> str:
    """``text`` cut with an ellipsis to ``width`` px."""
    if draw.textlength(text, font=font) <= width:
        return text
    while text and draw.textlength(text + "...", font=font) > width:
        text = text[:-1]
    return text + "..."
