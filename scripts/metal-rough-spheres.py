#!/usr/bin/env python3
"""Writes a glTF 2.0 test scene for arbor's metallic-roughness material: a 5 x 2 grid of
UV spheres, roughness 0, 0.25, 0.5, 0.75 and 1 across, metallic 0 (red plastic) above
and 1 (gold) below, on a grey floor; plus metalrough.toml, which frames it under a point
light and a uniform sky. The pictures in docs/materials.md come from it:

    scripts/metal-rough-spheres.py DIR && arbor render DIR/metalrough.toml --spp 128
"""
import json, math, os, struct, sys

TOML = '''[camera]
eye = [0.0, 1.5, 14.0]
look_at = [0.0, 0.6, 0.0]
up = [0.0, 1.0, 0.0]
vfov = 32.0
[film]
width = 480
height = 240
[render]
background = [0.35, 0.38, 0.45]
max_depth = 6
[[mesh]]
file = "metalrough.gltf"
[[light]]
type = "point"
position = [-4.0, 8.0, 10.0]
intensity = [120.0, 120.0, 120.0]
'''

if len(sys.argv) != 2 or sys.argv[1].startswith('-'):
    sys.exit('usage: metal-rough-spheres.py OUTPUT_DIR (writes metalrough.gltf, .bin and .toml there)')
out = sys.argv[1]
os.makedirs(out, exist_ok=True)
pos, nor, idx = [], [], []
S, T = 48, 24
for j in range(T + 1):
    th = math.pi * j / T
    for i in range(S + 1):
        ph = 2 * math.pi * i / S
        n = (math.sin(th) * math.cos(ph), math.cos(th), math.sin(th) * math.sin(ph))
        pos.append(n); nor.append(n)
for j in range(T):
    for i in range(S):
        a = j * (S + 1) + i; b = a + S + 1
        idx += [a, a + 1, b, a + 1, b + 1, b]
floor = [(-7, -1.2, -3), (7, -1.2, -3), (7, -1.2, 3), (-7, -1.2, 3)]
fidx = [0, 2, 1, 0, 3, 2]
bin_ = b''.join(struct.pack('<3f', *p) for p in pos) + b''.join(struct.pack('<3f', *n) for n in nor)
bin_ += struct.pack(f'<{len(idx)}I', *idx)
off_f = len(bin_)
bin_ += b''.join(struct.pack('<3f', *p) for p in floor) + b''.join(struct.pack('<3f', 0, 1, 0) for _ in floor)
bin_ += struct.pack('<6I', *fidx)
nv, ni = len(pos), len(idx)
views = [dict(buffer=0, byteOffset=0, byteLength=12 * nv), dict(buffer=0, byteOffset=12 * nv, byteLength=12 * nv),
         dict(buffer=0, byteOffset=24 * nv, byteLength=4 * ni),
         dict(buffer=0, byteOffset=off_f, byteLength=48), dict(buffer=0, byteOffset=off_f + 48, byteLength=48),
         dict(buffer=0, byteOffset=off_f + 96, byteLength=24)]
acc = [dict(bufferView=0, componentType=5126, count=nv, type='VEC3', min=[-1, -1, -1], max=[1, 1, 1]),
       dict(bufferView=1, componentType=5126, count=nv, type='VEC3'),
       dict(bufferView=2, componentType=5125, count=ni, type='SCALAR'),
       dict(bufferView=3, componentType=5126, count=4, type='VEC3', min=[-7, -1.2, -3], max=[7, -1.2, 3]),
       dict(bufferView=4, componentType=5126, count=4, type='VEC3'),
       dict(bufferView=5, componentType=5125, count=6, type='SCALAR')]
mats, meshes, nodes = [], [], []
for row, (metal, col) in enumerate([(0.0, [0.8, 0.08, 0.05, 1]), (1.0, [1.0, 0.77, 0.34, 1])]):
    for c in range(5):
        r = c / 4
        mats.append(dict(name=f'm{metal:g}r{r:g}', pbrMetallicRoughness=dict(baseColorFactor=col, metallicFactor=metal, roughnessFactor=r)))
        meshes.append(dict(primitives=[dict(attributes=dict(POSITION=0, NORMAL=1), indices=2, material=len(mats) - 1)]))
        nodes.append(dict(mesh=len(meshes) - 1, translation=[(c - 2) * 2.4, 1.2 - row * 2.4 + 1.2, 0], scale=[1, 1, 1]))
mats.append(dict(name='floor', pbrMetallicRoughness=dict(baseColorFactor=[0.5, 0.5, 0.5, 1], metallicFactor=0, roughnessFactor=1)))
meshes.append(dict(primitives=[dict(attributes=dict(POSITION=3, NORMAL=4), indices=5, material=len(mats) - 1)]))
nodes.append(dict(mesh=len(meshes) - 1))
doc = dict(asset=dict(version='2.0'), scene=0, scenes=[dict(nodes=list(range(len(nodes))))], nodes=nodes, meshes=meshes,
           materials=mats, accessors=acc, bufferViews=views, buffers=[dict(byteLength=len(bin_), uri='metalrough.bin')])
with open(os.path.join(out, 'metalrough.bin'), 'wb') as f:
    f.write(bin_)
with open(os.path.join(out, 'metalrough.gltf'), 'w') as f:
    json.dump(doc, f)
with open(os.path.join(out, 'metalrough.toml'), 'w') as f:
    f.write(TOML)
print(f'wrote {out}/metalrough.gltf, .bin and .toml')
