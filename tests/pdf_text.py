"""The text and page count of a PDF as headless Chromium (Skia) writes it, read in pure
Python, so that the report's PDF can be checked without poppler: objects by number,
Flate streams inflated, each page's content decoded through its fonts' ToUnicode maps
(Skia writes Type0 fonts, Identity-H, two-byte glyph codes, and shows text with Tj/TJ).

Only as much of PDF as Skia uses: no object streams, no encryption. A PDF outside that
gives no text, and a test reading it fails, as it should."""

from __future__ import annotations

import re
import unicodedata
import zlib
from pathlib import Path

OBJECT = re.compile(rb"(\d+)\s+0\s+obj\b(.*?)\bendobj", re.S)
REF = rb"(\d+)\s+0\s+R"


def _objects(data: bytes) -> dict[int, tuple[bytes, bytes | None]]:
    """Object number -> (its dictionary text, its inflated stream or None)."""
    out = {}
    for m in OBJECT.finditer(data):
        body = m.group(2)
        s = re.search(rb"stream\r?\n", body)
        if s is None:
            out[int(m.group(1))] = (body, None)
            continue
        head, raw = body[:s.start()], body[s.end():]
        raw = raw[:raw.rfind(b"endstream")]
        if b"/FlateDecode" in head:
            raw = zlib.decompressobj().decompress(raw)
        out[int(m.group(1))] = (head, raw)
    return out


def _cmap(stream: bytes) -> dict[int, str]:
    """A ToUnicode CMap's bfchar and bfrange entries: code -> text."""
    table: dict[int, str] = {}

    def text(hexstr: bytes) -> str:
        return bytes.fromhex(hexstr.decode()).decode("utf-16-be", errors="replace")

    for block in re.findall(rb"beginbfchar(.*?)endbfchar", stream, re.S):
        for src, dst in re.findall(rb"<([0-9A-Fa-f]+)>\s*<([0-9A-Fa-f]+)>", block):
            table[int(src, 16)] = text(dst)
    for block in re.findall(rb"beginbfrange(.*?)endbfrange", stream, re.S):
        for lo, hi, rest in re.findall(rb"<([0-9A-Fa-f]+)>\s*<([0-9A-Fa-f]+)>\s*(<[0-9A-Fa-f]+>|\[[^\]]*\])", block):
            lo, hi = int(lo, 16), int(hi, 16)
            if rest.startswith(b"["):
                for k, dst in enumerate(re.findall(rb"<([0-9A-Fa-f]+)>", rest)):
                    table[lo + k] = text(dst)
            else:
                start = bytes.fromhex(rest[1:-1].decode())
                for k in range(hi - lo + 1):
                    code = int.from_bytes(start, "big") + k
                    table[lo + k] = code.to_bytes(len(start), "big").decode("utf-16-be", errors="replace")
    return table


def _resolve(objects, value: bytes) -> bytes:
    m = re.fullmatch(rb"\s*" + REF + rb"\s*", value)
    return objects[int(m.group(1))][0] if m else value


def _fonts(objects, page_dict: bytes) -> dict[bytes, dict[int, str]]:
    res = re.search(rb"/Resources\s*(" + REF + rb"|<<.*>>)", page_dict, re.S)
    if res is None:
        return {}
    resources = _resolve(objects, res.group(1))
    fonts = re.search(rb"/Font\s*(" + REF + rb"|<<(.*?)>>)", resources, re.S)
    if fonts is None:
        return {}
    font_dict = _resolve(objects, fonts.group(1))
    out = {}
    for name, num in re.findall(rb"/([\w.+-]+)\s+" + REF, font_dict):
        uni = re.search(rb"/ToUnicode\s+" + REF, objects[int(num)][0])
        out[name] = _cmap(objects[int(uni.group(1))][1] or b"") if uni else {}
    return out


def _show(content: bytes, fonts: dict[bytes, dict[int, str]]) -> str:
    parts, cmap = [], {}
    for tok in re.finditer(rb"/([\w.+-]+)\s+[\d.]+\s+Tf|\[(.*?)\]\s*TJ|<([0-9A-Fa-f]*)>\s*Tj|(ET)", content, re.S):
        if tok.group(1) is not None:
            cmap = fonts.get(tok.group(1), {})
        elif tok.group(4) is not None:
            parts.append("\n")
        else:
            hexes = re.findall(rb"<([0-9A-Fa-f]*)>", tok.group(2)) if tok.group(2) is not None else [tok.group(3)]
            for h in hexes:
                codes = bytes.fromhex(h.decode())
                parts.append("".join(cmap.get(int.from_bytes(codes[i:i + 2], "big"), "")
                                     for i in range(0, len(codes) - 1, 2)))
    return "".join(parts)


def pdf_pages(path: str | Path) -> list[str]:
    """The text of each page, in page order (NFKC: the ligature ﬁ read as fi)."""
    objects = _objects(Path(path).read_bytes())
    root = next(d for d, _ in objects.values() if re.search(rb"/Type\s*/Pages\b", d) and b"/Parent" not in d)
    order = [int(n) for n in re.findall(REF, re.search(rb"/Kids\s*\[(.*?)\]", root, re.S).group(1))]
    pages = []
    for num in order:
        page = objects[num][0]
        contents = re.search(rb"/Contents\s*(\[.*?\]|" + REF + rb")", page, re.S).group(1)
        streams = [objects[int(n)][1] or b"" for n in re.findall(REF, contents)]
        pages.append(unicodedata.normalize("NFKC", _show(b"\n".join(streams), _fonts(objects, page))))
    return pages
