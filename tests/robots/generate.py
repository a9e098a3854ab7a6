#!/usr/bin/env python3
"""Generates the test robots arm6.urdf, arm9.urdf and arm12.urdf (run from the repository root).

Deterministic (fixed seeds, values rounded to 6 decimals). The robots exercise what the
reference chaser does not: oblique joint axes, non-zero joint-origin rpy, full inertia
tensors in rotated inertial frames, a fixed mounting flange before joint 1 (composed into
j1's origin), a massive tool fixed to the last link (merged into it), massless fixed frames
(ee, camera) and a massive battery fixed to the base off the chain (merged into the base).

Collision geometry (spec §13; it draws nothing from the random stream, so the rest of each
robot is unchanged by it): the base is the box whose inertia about its centre of mass is
the base's own (principal axes and moments of the tensor, a uniform box of the base's
mass), each link a capsule of radius 0.06 m from its joint to the next along the link's
x axis (the segment ends a radius short of both joints, so the capsule spans the link
length), and the tool, fixed to the last link, a sphere of 0.05 m at its centre of mass.
"""
import math
import random


def f(x):
    return repr(round(x, 6))


def rot(r, p, y):
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return [[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr]]


def inertia(m, size, rng):
    """A physically valid tensor (triangle inequality) with products of inertia."""
    a = rng.uniform(0.3, 1.0) * m * size * size
    b = rng.uniform(0.3, 1.0) * m * size * size
    c = rng.uniform(abs(a - b) + 0.05 * a, a + b)
    m_ = rot(rng.uniform(-3, 3), rng.uniform(-1.4, 1.4), rng.uniform(-3, 3))
    d = [a, b, c]
    return [[sum(m_[i][k] * d[k] * m_[j][k] for k in range(3)) for j in range(3)] for i in range(3)]


def inertial(m, xyz, rpy, i):
    return (f'    <inertial><origin xyz="{" ".join(f(v) for v in xyz)}" rpy="{" ".join(f(v) for v in rpy)}"/>'
            f'<mass value="{f(m)}"/>\n'
            f'      <inertia ixx="{f(i[0][0])}" ixy="{f(i[0][1])}" ixz="{f(i[0][2])}" '
            f'iyy="{f(i[1][1])}" iyz="{f(i[1][2])}" izz="{f(i[2][2])}"/></inertial>\n')


def eigen(a):
    """Eigenvalues and eigenvectors (columns) of a symmetric 3x3 matrix, by Jacobi rotations."""
    a = [row[:] for row in a]
    v = [[1.0 if i == j else 0.0 for j in range(3)] for i in range(3)]
    for _ in range(50):
        p, q = max(((0, 1), (0, 2), (1, 2)), key=lambda pq: abs(a[pq[0]][pq[1]]))
        if abs(a[p][q]) < 1e-15:
            break
        th = 0.5 * math.atan2(2 * a[p][q], a[q][q] - a[p][p])
        c, s = math.cos(th), math.sin(th)
        j = [[1.0 if i == k else 0.0 for k in range(3)] for i in range(3)]
        j[p][p], j[q][q], j[p][q], j[q][p] = c, c, s, -s
        jt = [list(r) for r in zip(*j)]
        a = [[sum(jt[i][k] * a[k][l] * j[l][m] for k in range(3) for l in range(3)) for m in range(3)] for i in range(3)]
        v = [[sum(v[i][k] * j[k][m] for k in range(3)) for m in range(3)] for i in range(3)]
    return [a[i][i] for i in range(3)], v


def matrix_rpy(r):
    pitch = math.asin(max(-1.0, min(1.0, -r[2][0])))
    return [math.atan2(r[2][1], r[2][2]), pitch, math.atan2(r[1][0], r[0][0])]


def box_collision(m, xyz, rpy, i):
    """The uniform box of mass m whose inertia about its centre is i (given in the frame
    rotated by rpy at xyz), as a <collision> in the link frame."""
    moments, axes = eigen(i)
    total = sum(moments)
    size = [math.sqrt(max(6.0 * (total - 2.0 * moments[k]) / m, 0.0)) for k in range(3)]
    # A proper rotation: flip the third axis if the eigenvectors are left-handed.
    det = (axes[0][0] * (axes[1][1] * axes[2][2] - axes[1][2] * axes[2][1])
           - axes[0][1] * (axes[1][0] * axes[2][2] - axes[1][2] * axes[2][0])
           + axes[0][2] * (axes[1][0] * axes[2][1] - axes[1][1] * axes[2][0]))
    if det < 0:
        for r in axes:
            r[2] = -r[2]
    frame = rot(*rpy)
    r = [[sum(frame[a][k] * axes[k][b] for k in range(3)) for b in range(3)] for a in range(3)]
    return (f'    <collision name="bus"><origin xyz="{" ".join(f(v) for v in xyz)}" '
            f'rpy="{" ".join(f(v) for v in matrix_rpy(r))}"/><geometry><box size="{" ".join(f(v) for v in size)}"/></geometry></collision>\n')


def capsule(name, length, r=0.06):
    return (f'    <collision name="{name}_capsule"><origin xyz="{f(length / 2)} 0 0" rpy="0 1.5707963267948966 0"/>'
            f'<geometry><cylinder radius="{f(r)}" length="{f(length - 2 * r)}"/></geometry></collision>\n')


def unit(v):
    n = math.sqrt(sum(x * x for x in v))
    return [x / n for x in v]


AXES = [[0, 0, 1], [0, 1, 0], [1, 0, 0], [0.6, 0, 0.8], [0, 0.6, -0.8], [1, 1, 0], [0.3, -0.2, 0.9], [0, 1, 0], [1, 0, 0.2]]


def base_link(m, rng):
    xyz, rpy, i = [0.05, -0.03, 0.02], [0.1, -0.05, 0.2], inertia(m, 0.9, rng)
    return '  <link name="base">\n' + inertial(m, xyz, rpy, i) + box_collision(m, xyz, rpy, i) + '  </link>\n'


def robot(name, n, seed, base_mass):
    rng = random.Random(seed)
    out = ['<?xml version="1.0"?>\n',
           f'<!-- {name}: a {n}-DOF test arm of this project, generated by tests/robots/generate.py.\n'
           '     Units: m, kg, kg m^2, rad, rad/s. -->\n',
           f'<robot name="{name}">\n',
           base_link(base_mass, rng),
           '  <joint name="battery_mount" type="fixed"><parent link="base"/><child link="battery"/>'
           '<origin xyz="-0.6 0.2 -0.3" rpy="0 0.3 0"/></joint>\n',
           '  <link name="battery">\n' + inertial(40.0, [0.0, 0.0, 0.05], [0, 0, 0.4], inertia(40.0, 0.25, rng)) + '  </link>\n',
           '  <joint name="camera_mount" type="fixed"><parent link="base"/><child link="camera"/>'
           '<origin xyz="0.7 0 0.4" rpy="0 -0.5 0"/></joint>\n  <link name="camera"/>\n',
           '  <joint name="flange" type="fixed"><parent link="base"/><child link="mount"/>'
           '<origin xyz="0.9 0.1 0.45" rpy="0.2 0 -0.1"/></joint>\n  <link name="mount"/>\n']
    parent, prev_len = "mount", 0.0
    for i in range(1, n + 1):
        ax = unit(AXES[(i - 1) % len(AXES)])
        length = rng.uniform(0.25, 0.9)
        rpy = [rng.uniform(-0.8, 0.8), rng.uniform(-0.6, 0.6), rng.uniform(-0.8, 0.8)]
        xyz = [0.0, 0.0, 0.0] if i == 1 else [prev_len, rng.uniform(-0.05, 0.05), rng.uniform(-0.05, 0.05)]
        lo, hi = -rng.uniform(2.2, 2.9), rng.uniform(2.2, 2.9)
        out.append(f'  <joint name="j{i}" type="revolute"><parent link="{parent}"/><child link="l{i}"/>\n'
                   f'    <origin xyz="{" ".join(f(v) for v in xyz)}" rpy="{" ".join(f(v) for v in rpy)}"/>'
                   f'<axis xyz="{" ".join(repr(v) for v in ax)}"/>\n'
                   f'    <limit lower="{f(lo)}" upper="{f(hi)}" velocity="{f(rng.uniform(0.2, 0.35))}" effort="100"/></joint>\n')
        m = rng.uniform(3, 25)
        com = [length / 2, rng.uniform(-0.03, 0.03), rng.uniform(-0.03, 0.03)]
        out.append(f'  <link name="l{i}">\n' + inertial(m, com, [rng.uniform(-1, 1) for _ in range(3)], inertia(m, length / 2.5, rng))
                   + capsule(f"l{i}", length) + '  </link>\n')
        parent, prev_len = f"l{i}", length
    out.append(f'  <joint name="tool_mount" type="fixed"><parent link="l{n}"/><child link="tool"/>'
               f'<origin xyz="{f(prev_len)} 0 0" rpy="0 0.4 0.2"/></joint>\n')
    out.append('  <link name="tool">\n' + inertial(4.0, [0.05, 0.0, 0.01], [0.2, 0, 0], inertia(4.0, 0.12, rng))
               + '    <collision name="tool"><origin xyz="0.05 0.0 0.01" rpy="0 0 0"/><geometry><sphere radius="0.05"/></geometry></collision>\n'
               + '  </link>\n')
    out.append('  <joint name="ee_fixed" type="fixed"><parent link="tool"/><child link="ee"/>'
               '<origin xyz="0.12 0 0" rpy="0 0 0"/></joint>\n  <link name="ee"/>\n</robot>\n')
    return "".join(out)


if __name__ == "__main__":
    for name, n, seed, mass in [("arm6", 6, 6, 650.0), ("arm9", 9, 9, 1200.0), ("arm12", 12, 12, 1500.0)]:
        with open(f"tests/robots/{name}.urdf", "w") as fh:
            fh.write(robot(name, n, seed, mass))
