#!/usr/bin/env python3
"""Picks small, distinct seed inputs for tests/fuzz/corpus/<target>/ from the
files the test suite writes (under $TMPDIR/raysweep-tests after a ctest run)
and from datasets/. Kept for reproducibility; the picked corpora are committed.
Usage: tests/fuzz/tools/pick_seeds.py [TESTS_DIR]"""
import hashlib, os, re, sys
from pathlib import Path

root = Path(__file__).resolve().parents[3]
tests = Path(sys.argv[1] if len(sys.argv) > 1 else "/tmp/raysweep-tests")
corpus = root / "tests/fuzz/corpus"

def kind(p: Path):
    name = p.name.lower()
    head = p.read_bytes()[:2048]
    if name.endswith(".osm"): return "osm_xml"
    if name.endswith(".pbf"): return "osm_pbf"
    if name.endswith((".glb", ".gltf")): return "gltf"
    for ext in ("obj", "off", "ply", "csv", "toml"):
        if name.endswith("." + ext): return ext
    if name.endswith((".xml", ".sumocfg")):
        text = head.decode("utf-8", "replace")
        m = re.search(r"<([A-Za-z][\w-]*)", re.sub(r"<\?.*?\?>|<!--.*?-->", "", text, flags=re.S))
        tag = m.group(1) if m else ""
        if tag == "net": return "sumo_net"
        if tag == "fcd-export": return "fcd"
        if tag == "scene": return "mitsuba"
        if tag in ("routes", "additional", "configuration") or "vType" in text: return "vtypes"
        if tag == "osm": return "osm_xml"
    return None

limits = {"gltf": 6000, "ply": 4000, "mitsuba": 4000}
picked = {}
files = sorted(p for p in list(tests.rglob("*")) + list((root / "datasets").rglob("*")) if p.is_file())
for p in files:
    try:
        if p.stat().st_size > limits.get(kind(p) or "", 12000) or p.stat().st_size == 0: continue
    except OSError:
        continue
    k = kind(p)
    if not k: continue
    data = p.read_bytes()
    h = hashlib.sha1(data).hexdigest()[:16]
    picked.setdefault(k, {}).setdefault(h, (len(data), p))
for k, items in picked.items():
    # keep at most 24 per target, spread over the size range
    items = sorted(items.items(), key=lambda kv: kv[1][0])
    step = max(1, len(items) // 24)
    out = corpus / k
    out.mkdir(parents=True, exist_ok=True)
    for h, (_, p) in items[::step][:24]:
        (out / f"seed-{h}{''.join(p.suffixes[-1:])}").write_bytes(p.read_bytes())
    print(k, len(items), "->", len(list(out.iterdir())))
