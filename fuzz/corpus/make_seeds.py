#!/usr/bin/env python3
"""Writes the binary seeds of fuzz/corpus/fits and fuzz/corpus/image (standard library only, deterministic).

FITS files are written card by card as the standard says (2880-byte blocks, 80-character cards), so the
corpus holds what aosr's own writer never produces: integer BITPIX 8/16/32/64 with BSCALE/BZERO/BLANK, a
primary HDU without data followed by an IMAGE extension, NAXIS = 3 cubes, long-string CONTINUE cards and
HIERARCH keywords. PNG (8/16-bit grey, RGB, RGBA, palette, interlaced) and TIFF (8/16-bit, float32, RGB;
uncompressed, little- and big-endian) are written by hand for the same reason.

    python3 fuzz/corpus/make_seeds.py      # from the repository root; rewrites the files
"""
import math
import os
import struct
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))


def card(key, value=None, comment=None):
    if value is None:
        text = key
    else:
        if isinstance(value, bool):
            v = "T" if value else "F"
        elif isinstance(value, str):
            v = "'" + value.replace("'", "''").ljust(8) + "'"
        else:
            v = repr(value) if isinstance(value, float) else str(value)
        text = key.ljust(8) + "= " + (v.rjust(20) if not isinstance(value, str) else v)
        if comment:
            text += " / " + comment
    return text[:80].ljust(80)


def header(cards):
    h = "".join(cards) + "END".ljust(80)
    h += " " * ((-len(h)) % 2880)
    return h.encode("ascii")


def data_block(raw):
    return raw + b"\0" * ((-len(raw)) % 2880)


def pixels(rows, cols, planes=1):
    return [[[((x * 5 + y * 3 + p * 7) % 13) for x in range(cols)] for y in range(rows)] for p in range(planes)]


def pack(bitpix, values):
    fmt = {8: "B", 16: "h", 32: "i", 64: "q", -32: "f", -64: "d"}[bitpix]
    return struct.pack(">" + fmt * len(values), *values)


def flat(cube):
    return [v for plane in cube for row in plane for v in row]


def fits(bitpix, rows, cols, planes=1, extra=(), values=None):
    axes = [cols, rows] + ([planes] if planes > 1 else [])
    cards = [card("SIMPLE", True), card("BITPIX", bitpix), card("NAXIS", len(axes))]
    cards += [card("NAXIS%d" % (i + 1), n) for i, n in enumerate(axes)]
    cards += list(extra)
    vals = values if values is not None else flat(pixels(rows, cols, planes))
    if bitpix < 0:
        vals = [float(v) for v in vals]
    return header(cards) + data_block(pack(bitpix, vals))


def write(folder, name, data):
    os.makedirs(os.path.join(HERE, folder), exist_ok=True)
    with open(os.path.join(HERE, folder, name), "wb") as f:
        f.write(data)


def fits_seeds():
    write("fits", "f32-8x8.fits", fits(-32, 8, 8, extra=[card("OBJECT", "seed"), card("EXPTIME", 1.5)]))
    nan = [float("nan") if i == 9 else float(v) for i, v in enumerate(flat(pixels(6, 5)))]
    write("fits", "f64-6x5-nan.fits", fits(-64, 6, 5, values=nan))
    write("fits", "u8-bscale.fits", fits(8, 4, 6, extra=[card("BSCALE", 0.5), card("BZERO", 10.0)]))
    write("fits", "i16-blank.fits", fits(16, 5, 5, extra=[card("BLANK", 3), card("BZERO", 32768)]))
    write("fits", "i32-cube3.fits", fits(32, 4, 4, planes=3, extra=[card("BUNIT", "ADU")]))
    write("fits", "i64-4x3.fits", fits(64, 4, 3))
    write("fits", "f32-cube1.fits", header([card("SIMPLE", True), card("BITPIX", -32), card("NAXIS", 3),
                                            card("NAXIS1", 4), card("NAXIS2", 4), card("NAXIS3", 1)])
          + data_block(pack(-32, [float(v) for v in flat(pixels(4, 4))])))
    long_text = "a long string value that needs the CONTINUE convention because it is longer than one card &"
    write("fits", "header-rich.fits", fits(-32, 3, 3, extra=[
        card("LONGSTR", long_text[:60] + "&'"[:0]), card("CONTINUE  '" + long_text[60:] + "'"),
        card("HIERARCH ESO DET DIT = 0.5"), card("FLAG", False), card("BIG", 123456789012345678901234),
        card("DEXP", "1.0D+03".replace("'", "")), card("CPLX   = (1.0, 2.0)"), card("COMMENT a comment"),
        card("HISTORY history"), card("NOVALUE")]))
    primary = header([card("SIMPLE", True), card("BITPIX", 8), card("NAXIS", 0), card("EXTEND", True)])
    ext = header([card("XTENSION", "IMAGE"), card("BITPIX", -32), card("NAXIS", 2), card("NAXIS1", 5),
                  card("NAXIS2", 4), card("PCOUNT", 0), card("GCOUNT", 1)]) + data_block(
        pack(-32, [float(v) for v in flat(pixels(4, 5))]))
    write("fits", "extension-image.fits", primary + ext)


def png_chunk(kind, data):
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xffffffff)


def png(width, height, depth, colour, rows, interlace=0, palette=None):
    raw = b"".join(b"\0" + r for r in rows)
    out = b"\x89PNG\r\n\x1a\n" + png_chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, depth, colour, 0, 0, interlace))
    if palette:
        out += png_chunk(b"PLTE", palette)
    return out + png_chunk(b"IDAT", zlib.compress(raw, 9)) + png_chunk(b"IEND", b"")


def tiff(width, height, bits, samples, fmt, data, little=True):
    e = "<" if little else ">"
    entries = [(256, 3, 1, width), (257, 3, 1, height), (258, 3, 1, bits), (259, 3, 1, 1),
               (262, 3, 1, 2 if samples == 3 else 1), (273, 4, 1, 0), (277, 3, 1, samples),
               (278, 3, 1, height), (279, 4, 1, len(data)), (339, 3, 1, fmt)]
    ifd_offset = 8
    data_offset = ifd_offset + 2 + 12 * len(entries) + 4
    out = (b"II*\0" if little else b"MM\0*") + struct.pack(e + "I", ifd_offset) + struct.pack(e + "H", len(entries))
    for tag, typ, count, value in entries:
        if tag == 273:
            value = data_offset
        if typ == 3:
            out += struct.pack(e + "HHIH2x", tag, typ, count, value)
        else:
            out += struct.pack(e + "HHII", tag, typ, count, value)
    return out + struct.pack(e + "I", 0) + data


def image_seeds():
    w, h = 9, 7
    grey = [bytes((x * 29 + y * 17) % 256 for x in range(w)) for y in range(h)]
    write("image", "grey8.png", png(w, h, 8, 0, grey))
    write("image", "grey16.png", png(w, h, 16, 0, [b"".join(struct.pack(">H", v * 257) for v in r) for r in grey]))
    write("image", "rgb8.png", png(w, h, 8, 2, [bytes(c for v in r for c in (v, 255 - v, v // 2)) for r in grey]))
    write("image", "rgba8.png", png(w, h, 8, 6, [bytes(c for v in r for c in (v, v, v, 128)) for r in grey]))
    write("image", "palette4.png", png(w, h, 4, 3, [bytes((((x % 4) << 4) | ((x + 1) % 4)) for x in range((w + 1) // 2)) for _ in range(h)],
                                       palette=bytes([0, 0, 0, 85, 85, 85, 170, 170, 170, 255, 255, 255])))
    write("image", "grey8-interlaced.png", png(w, h, 8, 0, grey, interlace=1))
    write("image", "grey1.png", png(16, 2, 1, 0, [b"\xa5\x5a", b"\xff\x00"]))
    write("image", "grey8.tif", tiff(w, h, 8, 1, 1, b"".join(grey)))
    write("image", "grey16-be.tif", tiff(w, h, 16, 1, 1, b"".join(struct.pack(">H", v * 257) for r in grey for v in r), little=False))
    write("image", "float32.tif", tiff(w, h, 32, 1, 3, b"".join(struct.pack("<f", v / 255.0) for r in grey for v in r)))
    write("image", "rgb8.tif", tiff(w, h, 8, 3, 1, b"".join(bytes(c for v in r for c in (v, v // 2, 255 - v)) for r in grey)))
    write("image", "f32-8x8.fits", fits(-32, 8, 8))


if __name__ == "__main__":
    fits_seeds()
    image_seeds()
