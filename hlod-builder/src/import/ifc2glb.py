# IFC to glTF for hlod-build: IfcOpenShell's geometry iterator, one node per
# IfcProduct with a shape, named "Class:Name:GlobalId" (the names the
# importer reads the IFC class from, as BIM exports write them), its
# GlobalId, type, name, storey (and its elevation), building and site in the
# node's extras. Products that share a
# representation share a mesh; each mesh has a primitive per material, its
# colour and transparency from the IFC styles. IFC's Z-up becomes glTF's Y-up
# in a root node. Single-threaded and in file order, so that the same IFC
# file gives the same bytes.
#
#   python3 ifc2glb.py MODEL.ifc OUT.glb
#
# Exit status: 0 written; 3 IfcOpenShell is not installed; 4 the file is not
# IFC IfcOpenShell can read; 5 nothing in it has a shape.
import json
import struct
import sys

try:
    import ifcopenshell
    import ifcopenshell.geom
    import ifcopenshell.util.element
except ImportError as e:
    sys.stderr.write("IfcOpenShell is not installed in this Python (%s)\n" % e)
    sys.exit(3)


def spatial_of(product):
    """The storey, building and site above a product (or that it is), and the
    storey's elevation: the model tree's levels."""
    out = {}
    try:
        if product.is_a("IfcSpatialStructureElement"):
            c = product
        else:
            c = ifcopenshell.util.element.get_container(product)
        while c is not None:
            for cls, key in (("IfcBuildingStorey", "storey"), ("IfcBuilding", "building"),
                             ("IfcSite", "site")):
                if c.is_a(cls) and key not in out and c.Name:
                    out[key] = c.Name
                    if key == "storey" and getattr(c, "Elevation", None) is not None:
                        out["storey_elevation"] = float(c.Elevation)
            c = ifcopenshell.util.element.get_aggregate(c)
    except Exception:
        pass
    return out


def main(src, out):
    try:
        f = ifcopenshell.open(src)
    except Exception as e:
        sys.stderr.write("not an IFC file IfcOpenShell can read: %s\n" % e)
        sys.exit(4)
    settings = ifcopenshell.geom.settings()
    it = ifcopenshell.geom.iterator(settings, f, 1)
    bin_ = bytearray()
    views, accessors, meshes, nodes, materials = [], [], [], [], []
    material_index, mesh_of = {}, {}

    def view(data, target):
        while len(bin_) % 4:
            bin_.append(0)
        views.append({"buffer": 0, "byteOffset": len(bin_), "byteLength": len(data), "target": target})
        bin_.extend(data)
        return len(views) - 1

    def material(m):
        d = m.diffuse
        rgb = [round(float(d.r()), 4), round(float(d.g()), 4), round(float(d.b()), 4)]
        t = float(m.transparency) if m.has_transparency() else 0.0
        if not (0.0 <= t <= 1.0):
            t = 0.0
        key = (m.name, tuple(rgb), round(1.0 - t, 4))
        if key not in material_index:
            mat = {
                "name": m.name,
                "pbrMetallicRoughness": {
                    "baseColorFactor": rgb + [key[2]],
                    "metallicFactor": 0.0,
                    "roughnessFactor": 0.9,
                },
            }
            if key[2] < 1.0:
                mat["alphaMode"] = "BLEND"
            material_index[key] = len(materials)
            materials.append(mat)
        return material_index[key]

    def mesh(g, cls):
        verts, faces, mids = g.verts, g.faces, g.material_ids
        if len(faces) == 0:
            return None
        by_mat = {}
        for k in range(len(faces) // 3):
            by_mat.setdefault(mids[k] if k < len(mids) else -1, []).extend(faces[3 * k:3 * k + 3])
        prims = []
        for mid in sorted(by_mat):
            idx = by_mat[mid]
            used = sorted(set(idx))
            remap = {v: i for i, v in enumerate(used)}
            pos = []
            for v in used:
                pos.extend(verts[3 * v:3 * v + 3])
            lo = [min(pos[c::3]) for c in range(3)]
            hi = [max(pos[c::3]) for c in range(3)]
            pv = view(struct.pack("<%df" % len(pos), *pos), 34962)
            accessors.append({"bufferView": pv, "componentType": 5126, "count": len(used),
                              "type": "VEC3", "min": lo, "max": hi})
            iv = view(struct.pack("<%dI" % len(idx), *[remap[v] for v in idx]), 34963)
            accessors.append({"bufferView": iv, "componentType": 5125, "count": len(idx),
                              "type": "SCALAR"})
            prim = {"attributes": {"POSITION": len(accessors) - 2}, "indices": len(accessors) - 1}
            if 0 <= mid < len(g.materials):
                prim["material"] = material(g.materials[mid])
            prims.append(prim)
        meshes.append({"name": cls, "primitives": prims})
        return len(meshes) - 1

    if it.initialize():
        while True:
            shape = it.get()
            product = f.by_id(shape.id)
            cls = product.is_a()
            g = shape.geometry
            if g.id not in mesh_of:
                mesh_of[g.id] = mesh(g, cls)
            m = mesh_of[g.id]
            if m is not None:
                name = product.Name or ""
                guid = product.GlobalId
                node = {"name": "%s:%s:%s" % (cls, name, guid), "mesh": m}
                mat = [float(x) for x in shape.transformation.matrix]
                if mat != [1.0, 0, 0, 0, 0, 1.0, 0, 0, 0, 0, 1.0, 0, 0, 0, 0, 1.0]:
                    node["matrix"] = mat
                extras = {"GlobalId": guid, "type": cls}
                if name:
                    extras["Name"] = name
                extras.update(spatial_of(product))
                node["extras"] = extras
                nodes.append(node)
            if not it.next():
                break
    if not nodes:
        sys.stderr.write("no product in the file has a shape\n")
        sys.exit(5)
    nodes.append({"name": "IFC (Z up)", "children": list(range(len(nodes))),
                  "matrix": [1.0, 0, 0, 0, 0, 0, -1.0, 0, 0, 1.0, 0, 0, 0, 0, 0, 1.0]})
    doc = {
        "asset": {"version": "2.0", "generator": "hlod-build ifc2glb.py (IfcOpenShell %s)" % ifcopenshell.version},
        "scene": 0,
        "scenes": [{"nodes": [len(nodes) - 1]}],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": len(bin_)}],
    }
    j = json.dumps(doc, separators=(",", ":"), ensure_ascii=False).encode("utf-8")
    j += b" " * (-len(j) % 4)
    while len(bin_) % 4:
        bin_.append(0)
    total = 12 + 8 + len(j) + 8 + len(bin_)
    with open(out, "wb") as o:
        o.write(struct.pack("<4sII", b"glTF", 2, total))
        o.write(struct.pack("<I4s", len(j), b"JSON") + j)
        o.write(struct.pack("<I4s", len(bin_), b"BIN\0") + bytes(bin_))


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.stderr.write("usage: ifc2glb.py MODEL.ifc OUT.glb\n")
        sys.exit(2)
    main(sys.argv[1], sys.argv[2])
