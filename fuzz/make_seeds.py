#!/usr/bin/env python3
"""Writes the binary and text seeds of fuzz/corpus/ (the scene seeds are copies of shipped and
broken scenes). The formats: docs/trajectory.md and docs/haptics-protocol.md; both checksum
with zlib's CRC-32."""
import os
import struct
import zlib

root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "corpus")


def write(target, name, data):
    with open(os.path.join(root, target, name), "wb") as f:
        f.write(data if isinstance(data, bytes) else data.encode())


def sample(t, x, buttons=0, q=(1.0, 0.0, 0.0, 0.0), force=(0.0, 0.0, 0.0)):
    return struct.pack("<8dI3f", t, x, 0.01, 0.02, *q, buttons, *force)


def chunk(samples):
    payload = b"".join(samples)
    return b"CHNK" + struct.pack("<III", len(samples), len(payload), zlib.crc32(payload)) + payload


header = b"INCTRAJ\0" + struct.pack("<III", 1, 32, 0) + bytes(12)
two_chunks = header + chunk([sample(0.0, 0.0), sample(0.001, 0.001, 1)]) + chunk([sample(0.002, 0.002, 1, force=(0.5, 0, 0))])
write("trajectory", "two_chunks.traj", two_chunks)
write("trajectory", "truncated.traj", two_chunks[:-7])
write("trajectory", "header_only.traj", header)
write("trajectory", "long_header.traj", b"INCTRAJ\0" + struct.pack("<III", 1, 40, 0) + bytes(20) + chunk([sample(0.5, 0.1)]))


def stops(records):  # version 2: (step, solve, iterations) of CGs a real-time budget stopped
    payload = b"".join(struct.pack("<QII", *r) for r in records)
    return b"CGST" + struct.pack("<III", len(records), len(payload), zlib.crc32(payload)) + payload


header2 = b"INCTRAJ\0" + struct.pack("<III", 2, 32, 0) + bytes(12)
write("trajectory", "cg_stops.traj", header2 + chunk([sample(0.0, 0.0), sample(0.01, 0.001, 1)]) + stops([(1, 0, 3), (1, 1, 4)]) +
      chunk([sample(0.02, 0.002, 1)]) + stops([(2, 0, 7)]))

write("trajectory_csv", "keyframes.csv", "time,x,y,z,qw,qx,qy,qz,buttons\n0,0,0,0.05,1,0,0,0,0\n0.5,0.01,0,0.03,1,0,0,0,1\n1,0.02,0,0.03,0.7071,0.7071,0,0,1\n")
write("trajectory_csv", "with_force.csv", "time,x,y,z,qw,qx,qy,qz,buttons,fx,fy,fz\r\n0,0,0,0,1,0,0,0,0,0,0,0\r\n\r\n1e-3,1e-3,-2e-3,0.5,2,0,0,0,3,0.25,-1.5,0\r\n")

def pose(session, sequence, timestamp, position, q, buttons=0):
    body = struct.pack("<IBBH", 0x48434E49, 1, 1, 92) + struct.pack("<IIQq", session, buttons, sequence, timestamp)
    body += struct.pack("<3d4d", *position, *q)
    return body + struct.pack("<I", zlib.crc32(body))

def force(session, state, sequence, pose_sequence, timestamp, f):
    body = struct.pack("<IBBH", 0x48434E49, 1, 2, 68) + struct.pack("<IB3xQQq", session, state, sequence, pose_sequence, timestamp)
    body += struct.pack("<3d", *f)
    return body + struct.pack("<I", zlib.crc32(body))

write("udp_pose", "pose.bin", pose(7, 1, 1_000_000, (0.01, -0.02, 0.03), (1, 0, 0, 0), 1))
write("udp_pose", "pose_turned.bin", pose(7, 2, 2_000_000, (0, 0, 0), (0.70710678, 0, 0.70710678, 0)))
write("udp_pose", "force.bin", force(7, 1, 3, 2, 3_000_000, (0.1, 0.2, -0.3)))

tetra_obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
write("mesh_obj", "tetra.obj", tetra_obj)
tri = [((0, 0, 0), (0, 1, 0), (1, 0, 0)), ((0, 0, 0), (1, 0, 0), (0, 0, 1)), ((0, 0, 0), (0, 0, 1), (0, 1, 0)), ((1, 0, 0), (0, 1, 0), (0, 0, 1))]
stl = "solid t\n" + "".join("facet normal 0 0 0\nouter loop\n" + "".join("vertex %g %g %g\n" % v for v in t) + "endloop\nendfacet\n" for t in tri) + "endsolid t\n"
write("mesh_stl", "tetra_ascii.stl", stl)
binary = bytes(80) + struct.pack("<I", len(tri)) + b"".join(struct.pack("<3f", 0, 0, 0) + b"".join(struct.pack("<3f", *v) for v in t) + b"\0\0" for t in tri)
write("mesh_stl", "tetra_binary.stl", binary)
ply = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 4\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n"
write("mesh_ply", "tetra_ascii.ply", ply)
write("mesh_obj", "open.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
# incise's own readers (engine/surface_file.hpp): binary PLY of both byte orders with other
# coordinate, count and index types, skipped properties and elements; OBJ's corner forms,
# relative indices, objects and groups.
tetra_v = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
tetra_f = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
for fmt, e, c, ctype, n, ntype in [("binary_little_endian", "<", "d", "double", "B", "uchar"),
                                   ("binary_big_endian", ">", "h", "short", "I", "uint")]:
    header = (f"ply\nformat {fmt} 1.0\ncomment tetrahedron\nelement vertex 4\nproperty {ctype} x\nproperty uchar red\n"
              f"property {ctype} y\nproperty {ctype} z\nelement face 4\nproperty list {ntype} int vertex_indices\n"
              "property float quality\nelement edge 1\nproperty list uchar ushort ends\nend_header\n")
    data = b"".join(struct.pack(e + c + "B" + c + c, v[0], 255, v[1], v[2]) for v in tetra_v)
    data += b"".join(struct.pack(e + n + "iiif", 3, *f, 0.5) for f in tetra_f) + struct.pack(e + "BHH", 2, 0, 1)
    write("mesh_ply", f"tetra_{fmt}.ply", header.encode() + data)
write("mesh_obj", "tetra_forms.obj", "# tetrahedron, every corner form\no a\nv 0 0 0\nv 1 0 0 1.0\nv 0 1 0\n"
      "v 0 0 1 0.5 0.5 0.5\nvt 0 0\nvn 0 0 1\ng b\nf 1/1 3//1 2/1/1\nf -4 -3 -1\no c\nf 1//-1 4/-1 3\nf 2 3 4 # last\n")

# Tetrahedral meshes (first byte: 0 .msh, 1 .vtk, 2 .vtu; 3 and 6 are .msh too): two tetrahedra
# on five nodes with a triangle to skip and an unused node, in each format the readers take.
msh2 = ("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Comments\nanything\n$EndComments\n$Nodes\n6\n1 0 0 0\n2 1 0 0\n"
        "3 0 1 0\n4 0 0 1\n5 1 1 1\n6 9 9 9\n$EndNodes\n$Elements\n3\n1 2 2 0 1 2 3 4\n2 4 2 0 1 1 2 3 4\n"
        "7 4 2 0 1 5 4 3 2\n$EndElements\n")
write("tet_mesh", "two_tets_v2.msh", b"\0" + msh2.encode())
msh4 = ("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 5 1 5\n3 1 0 5\n1\n2\n3\n4\n5\n0 0 0\n1 0 0\n0 1 0\n"
        "0 0 1\n1 1 1\n$EndNodes\n$Elements\n2 3 1 3\n2 1 2 1\n1 2 3 4\n3 1 4 2\n2 1 2 3 4\n3 5 4 3 2\n$EndElements\n")
write("tet_mesh", "two_tets_v4.msh", b"\3" + msh4.encode())
corners = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
msh4_binary = (b"$MeshFormat\n4.1 1 8\n" + struct.pack("<i", 1) + b"\n$EndMeshFormat\n$Nodes\n"
               + struct.pack("<QQQQ", 1, 4, 1, 4) + struct.pack("<iiiQ", 3, 1, 0, 4)
               + b"".join(struct.pack("<Q", i + 1) for i in range(4)) + b"".join(struct.pack("<ddd", *p) for p in corners)
               + b"\n$EndNodes\n$Elements\n" + struct.pack("<QQQQ", 1, 1, 1, 1) + struct.pack("<iiiQ", 3, 1, 4, 1)
               + struct.pack("<QQQQQ", 1, 1, 2, 3, 4) + b"\n$EndElements\n")
write("tet_mesh", "tet_binary_v4.msh", b"\6" + msh4_binary)
vtk = ("# vtk DataFile Version 3.0\nt\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 5 float\n0 0 0 1 0 0 0 1 0 0 0 1\n"
       "1 1 1\nCELLS 3 14\n4 0 1 2 3\n4 4 3 2 1\n3 1 2 3\nCELL_TYPES 3\n10\n10\n5\n")
write("tet_mesh", "two_tets.vtk", b"\1" + vtk.encode())
vtu = ('<VTKFile type="UnstructuredGrid"><UnstructuredGrid><Piece><Points><DataArray format="ascii">'
       '0 0 0 1 0 0 0 1 0 0 0 1</DataArray></Points><Cells><DataArray Name="connectivity" format="ascii">0 1 2 3'
       '</DataArray><DataArray Name="offsets" format="ascii">4</DataArray><DataArray Name="types" format="ascii">10'
       '</DataArray></Cells></Piece></UnstructuredGrid></VTKFile>')
write("tet_mesh", "tet.vtu", b"\2" + vtu.encode())
