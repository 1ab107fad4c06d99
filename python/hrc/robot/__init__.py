"""A lab's own robot brought in: `hrc robot add` (robots/README.md, "Bring your own robot").

- `expand`: a xacro file expanded (`$(find PKG)` resolved against given folders);
- `add`: a description package, URDF or xacro made into a robot folder every view reads (its
  meshes found and copied beside it, all missing ones named at once), and a report of its chain,
  joints, reach, forward kinematics checked against pybullet's, and IK figures on its chain.
"""
