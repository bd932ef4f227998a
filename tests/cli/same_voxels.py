"""same_voxels.py A B ENC_A ENC_B: two NRRD files (attached data) hold the same voxels byte for
byte, A with encoding ENC_A and B with ENC_B (raw or gzip), and the same header otherwise."""
import gzip
import sys


def read(path):
    head, _, data = open(path, "rb").read().partition(b"\n\n")
    lines = head.decode().splitlines()
    enc = [l.split(":", 1)[1].strip() for l in lines if l.startswith("encoding:")]
    assert len(enc) == 1, (path, enc)
    rest = [l for l in lines if not l.startswith("encoding:")]
    return enc[0], rest, gzip.decompress(data) if enc[0] in ("gzip", "gz") else data


a, b, want_a, want_b = sys.argv[1:5]
ea, ha, da = read(a)
eb, hb, db = read(b)
assert (ea, eb) == (want_a, want_b), (a, ea, b, eb)
assert ha == hb, (ha, hb)
assert len(da) > 0 and da == db, (a, b, len(da), len(db))
