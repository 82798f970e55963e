"""Checks an XDMF companion written by flexipde against its HDF5 file: the XML parses, the mesh
has as many points as every referenced dataset describes, each referenced dataset exists with the
stated dimensions, and hyperslabs select one component inside the dataset's shape.

    /usr/bin/python3 tests/check_xdmf.py file.xmf [expected_attribute ...]
"""
import os
import sys
import xml.etree.ElementTree as ET

import h5py
import numpy as np

xmf = sys.argv[1]
expected = sys.argv[2:]
root = ET.parse(xmf).getroot()
grid = root.find("Domain/Grid")
topo = grid.find("Topology")
npoints = int(np.prod([int(v) for v in topo.get("Dimensions").split()]))
names = []
for attr in grid.findall("Attribute"):
    names.append(attr.get("Name"))
    item = attr.find("DataItem")
    dims = [int(v) for v in item.get("Dimensions").split()]
    assert int(np.prod(dims)) == npoints, (attr.get("Name"), dims, npoints)
    if item.get("ItemType") == "HyperSlab":
        sel, data = item.findall("DataItem")
        start, stride, count = np.array(sel.text.split(), dtype=int).reshape(3, -1)
        h5ref = data.text.strip()
        ddims = [int(v) for v in data.get("Dimensions").split()]
        assert all(start + (count - 1) * stride < np.array(ddims)), (attr.get("Name"), start, count, ddims)
    else:
        h5ref, ddims = item.text.strip(), dims
    fname, path = h5ref.split(":")
    with h5py.File(os.path.join(os.path.dirname(os.path.abspath(xmf)), fname), "r") as f:
        assert path in f, (h5ref, "missing")
        shape = f[path].shape
        assert int(np.prod(shape)) == int(np.prod(ddims)), (h5ref, shape, ddims)
        assert np.all(np.isfinite(f[path][...])), (h5ref, "not finite")
for e in expected:
    assert e in names, (e, names)
print("xdmf ok: %s, %d points, %d attributes: %s" % (xmf, npoints, len(names), " ".join(names)))
