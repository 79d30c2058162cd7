#!/usr/bin/env python3
"""Writes the seed corpus of the fuzz targets (fuzz/corpus/<target>/): a few valid inputs and a
few malformed ones per parser, each tiny. Reproducers of fixed findings are kept beside them
under their own names (not written here). Run from anywhere: python3 fuzz/corpus/make_seeds.py
"""
import io
import os
import struct
import zipfile
import zlib

ROOT = os.path.dirname(os.path.abspath(__file__))


def put(target, name, data):
    folder = os.path.join(ROOT, target)
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, name), "wb") as f:
        f.write(data.encode("latin-1") if isinstance(data, str) else data)


# --- url: request targets, query strings, header values.
for name, text in {
    "target": "/api/v1/jobs?limit=10&state=queued",
    "segments": "/a/b%2Fc/?x=%20y+z&flag",
    "content-type": 'multipart/form-data; boundary="ab\\"c"; charset=utf-8',
    "disposition": 'form-data; name="images"; filename="C:\\photos\\a.jpg"',
    "rfc5987": "attachment; filename*=UTF-8''%e2%82%ac%20rates.jpg",
    "bad-escape": "/a%zz/%",
    "encoded-nul": "/x%00y?a=%00",
    "empty-pairs": "?&&=&a==b&",
    "unterminated": 'type; a="open',
    "absolute-form": "http://example.com/a",
}.items():
    put("url", name, text)

# --- range: 8 bytes of size (little-endian), then the Range / If-Range value.
for name, (size, text) in {
    "first-500": (1000, "bytes=0-499"),
    "suffix": (1000, "bytes=-500"),
    "open-end": (1000, "bytes=500-"),
    "etag-list": (10, '"abc", W/"def"'),
    "weak-etag": (10, 'W/"abc"'),
    "star": (10, "*"),
    "huge-first": (2**64 - 1, "bytes=18446744073709551615-18446744073709551615"),
    "zero-suffix": (0, "bytes=-0"),
    "reversed": (1000, "bytes=5-1"),
    "two-ranges": (1000, "bytes=0-1,2-3"),
    "overflow": (1000, "bytes=99999999999999999999999-"),
}.items():
    put("range", name, struct.pack("<Q", size) + text.encode())

# --- multipart: Content-Type line, one chunk-size byte, the body.
CRLF = "\r\n"


def multipart(boundary, parts, close=True, chunk="\x07"):
    body = "preamble" + CRLF
    for headers, content in parts:
        body += "--" + boundary + CRLF + CRLF.join(headers) + CRLF + CRLF + content + CRLF
    if close:
        body += "--" + boundary + "--" + CRLF + "epilogue"
    return "multipart/form-data; boundary=" + boundary + "\n" + chunk + body


photo = ['Content-Disposition: form-data; name="images"; filename="a.jpg"',
         "Content-Type: image/jpeg"]
options = ['Content-Disposition: form-data; name="options"']
put("multipart", "two-parts", multipart("XyZ", [(photo, "\xff\xd8\xff--XyZ-not"), (options, "{}")]))
put("multipart", "quoted-boundary",
    multipart('"a b"', [(photo, "x")]).replace("--\"a b\"", "--a b"))
put("multipart", "filename-star", multipart("b", [(
    ["Content-Disposition: form-data; name=images; filename*=UTF-8''%e2%82%ac.jpg"], "data")],
    chunk="\x00"))
put("multipart", "truncated", multipart("XyZ", [(photo, "abc")], close=False))
put("multipart", "no-name", multipart("XyZ", [(["Content-Disposition: form-data"], "x")]))
put("multipart", "no-disposition", multipart("XyZ", [(["Content-Type: text/plain"], "x")]))
put("multipart", "lf-only", multipart("XyZ", [(photo, "x")]).replace("\r\n", "\n"))
put("multipart", "padding", "multipart/form-data; boundary=q\n\x01--q \t\r\n" + CRLF.join(
    options) + CRLF + CRLF + "{}\r\n--q--\t\r\n")
put("multipart", "long-header", multipart("XyZ", [(photo + ["X-Pad: " + "p" * 600], "x")]))

# --- zip: archives as clients send them, and hostile ones.
JPEG_BYTES = b"\xff\xd8\xff\xe0" + b"\x00" * 40 + b"\xff\xd9"


def zip_of(entries, compression=zipfile.ZIP_DEFLATED):
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", compression) as z:
        for entry in entries:
            if isinstance(entry, zipfile.ZipInfo):
                z.writestr(entry, b"target")
            else:
                z.writestr(entry[0], entry[1])
    return out.getvalue()


put("zip", "two-photos", zip_of([("a.jpg", JPEG_BYTES), ("b/c.png", b"\x89PNG\r\n\x1a\n")]))
put("zip", "stored", zip_of([("a.jpg", JPEG_BYTES)], zipfile.ZIP_STORED))
put("zip", "macos-windows", zip_of([("__MACOSX/._a.jpg", b"x"), (".DS_Store", b"x"),
                                    ("Thumbs.db", b"x"), ("d/", b""), ("a.jpg", JPEG_BYTES),
                                    ("inner.zip", b"PK")]))
put("zip", "traversal", zip_of([("../evil.jpg", JPEG_BYTES)]))
put("zip", "absolute", zip_of([("/etc/evil.jpg", JPEG_BYTES)]))
link = zipfile.ZipInfo("link.jpg")
link.external_attr = (0o120777 << 16)
put("zip", "symlink", zip_of([link]))
put("zip", "zeros", zip_of([("z.jpg", b"\x00" * 200000)]))
put("zip", "truncated", zip_of([("a.jpg", JPEG_BYTES * 4)])[:-30])
put("zip", "empty", zip_of([]))

# --- options: the JSON of job options.
for name, text in {
    "two-fields": '{"min_image_side": 200, "use_exif": false}',
    "held-out": '{"held_out_photos": ["0001.jpg"], "principal_point": "refine"}',
    "all-off": '{"dense_matching": false, "mesh": false, "texture": false, "num_threads": 2}',
    "empty": "",
    "array": "[1, 2]",
    "wrong-type": '{"min_image_side": "big"}',
    "out-of-range": '{"max_image_pixels": 1e300, "num_threads": -1}',
    "unknown": '{"colour": "blue"}',
    "nested": "[" * 200 + "]" * 200,
    "bad-utf8": '{"principal_point": "\xc3"}',
    "duplicate": '{"mesh": true, "mesh": 1}',
}.items():
    put("options", name, text)

# --- image_header and exif: tiny JPEG, PNG and TIFF files.


def png(width, height, chunks_after=True):
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(
            ">I", zlib.crc32(kind + data) & 0xffffffff)
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    raw = b"".join(b"\x00" + b"\x80" * width for _ in range(min(height, 4)))
    out = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(raw))
    return out + chunk(b"IEND", b"") if chunks_after else out


def tiff_ifd(entries, little=True, extra=b""):
    """A TIFF/EXIF block: header, IFD0 with (tag, type, count, value bytes) entries."""
    e = "<" if little else ">"
    head = (b"II" if little else b"MM") + struct.pack(e + "HI", 42, 8)
    count = len(entries)
    data_at = 8 + 2 + 12 * count + 4
    ifd, data = struct.pack(e + "H", count), b""
    for tag, kind, n, value in entries:
        if len(value) <= 4:
            ifd += struct.pack(e + "HHI", tag, kind, n) + value.ljust(4, b"\x00")
        else:
            ifd += struct.pack(e + "HHII", tag, kind, n, data_at + len(data))
            data += value
    return head + ifd + struct.pack(e + "I", 0) + data + extra


def short(v):
    return struct.pack("<H", v)


def rational(num, den):
    return struct.pack("<II", num, den)


def jpeg(width, height, app1=b"", eoi=True):
    sof = b"\xff\xc0" + struct.pack(">HBHHB", 11, 8, height, width, 1) + b"\x01\x11\x00"
    sos = b"\xff\xda" + struct.pack(">HB", 8, 1) + b"\x01\x00\x00\x3f\x00"
    out = b"\xff\xd8"
    if app1:
        out += b"\xff\xe1" + struct.pack(">H", len(app1) + 2) + app1
    out += sof + sos + b"\x12\x34\x56"
    return out + (b"\xff\xd9" if eoi else b"")


exif = b"Exif\x00\x00" + tiff_ifd([
    (0x010F, 2, 6, b"Canon\x00"), (0x0110, 2, 4, b"EOS\x00"), (0x0112, 3, 1, short(6)),
    (0x920A, 5, 1, rational(35, 1)), (0xA405, 3, 1, short(50)),
    (0xA20E, 5, 1, rational(4000, 1)), (0xA210, 3, 1, short(2))])
bad_exif = b"Exif\x00\x00II*\x00\xff\xff\xff\x7f\x05\x00"
zero_focal = b"Exif\x00\x00" + tiff_ifd([(0x0112, 3, 1, short(9)), (0x920A, 5, 1, rational(0, 0))])
tiff = tiff_ifd([(256, 3, 1, short(2)), (257, 3, 1, short(2)), (258, 3, 1, short(8)),
                 (259, 3, 1, short(1)), (262, 3, 1, short(1)), (273, 4, 1, struct.pack("<I", 8)),
                 (277, 3, 1, short(1)), (278, 3, 1, short(2)), (279, 4, 1, struct.pack("<I", 4))])
tiff_bad_strip = tiff.replace(struct.pack("<HHII", 273, 4, 1, 8),
                              struct.pack("<HHII", 273, 4, 1, 0xFFFFFFF0))

for target in ("image_header", "exif"):
    put(target, "jpeg-exif", jpeg(120, 100, exif))
    put(target, "png", png(4, 4))
    put(target, "tiff", tiff)
put("image_header", "jpeg-plain", jpeg(64, 48))
put("image_header", "jpeg-no-eoi", jpeg(64, 48, eoi=False))
put("image_header", "jpeg-huge", jpeg(65535, 65535))
put("image_header", "png-no-iend", png(4, 4, chunks_after=False))
put("image_header", "png-zero-width", png(0, 4))
put("image_header", "tiff-strip-outside", tiff_bad_strip)
put("image_header", "tiff-big-endian", tiff_ifd([(256, 3, 1, b"\x00\x02")], little=False))
put("exif", "jpeg-bad-ifd", jpeg(64, 48, bad_exif))
put("exif", "jpeg-zero-focal", jpeg(64, 48, zero_focal))
put("exif", "png-exif-chunk", png(4, 4)[:-12] + struct.pack(">I", len(exif) - 6) + b"eXIf" +
    exif[6:] + b"\x00" * 4 + png(4, 4)[-12:])

# --- config: the INI-style configuration file.
for name, text in {
    "server": "data = /srv/reconduit\n[server]\nport = 8080\nthreads = 4\n",
    "both-sections": "data = d\n[server]\nhost = 0.0.0.0\n[worker]\nlease = 60\n",
    "comments": "# a comment\n\nverbose = true\nlease = 1.5  \nmax-upload-bytes = 1048576\n",
    "unknown-section": "[wroker]\nport = 1\n",
    "twice": "port = 1\n[server]\nport = 2\n",
    "bad-int": "port = 99999999999999\nthreads = -\n",
    "no-equals": "port 1\n",
    "open-section": "[server\nport = 1\n",
    "empty-name": "=\n= x\n",
}.items():
    put("config", name, text)
