// The scenario's world frame (z up, origin at the board's top centre, the participant at -y
// looking +y) inside three.js's (y up). Everything of the scene hangs under one root group whose
// pose is the calibration: the standing point (x, y on the floor) and the table height.
import * as THREE from 'three';

// world -> three: (x, y, z) -> (x, z, -y), a rotation of -90 degrees about x
export const Q_WORLD = new THREE.Quaternion().setFromAxisAngle(new THREE.Vector3(1, 0, 0), -Math.PI / 2);
const Q_WORLD_INV = Q_WORLD.clone().invert();

export const DEFAULT_TABLE_HEIGHT = 0.9; // board top above the floor, m
export const DEFAULT_STAND = [0.0, -0.7]; // where the participant stands (the XR origin), m

/** Poses the root group so that the floor point `origin` (XR x, z; the XR origin by default)
 * is at world (stand_x, stand_y, -table_height): three = R * world + t. */
export function placeRoot(root, tableHeight, stand, origin = [0, 0]) {
  root.quaternion.copy(Q_WORLD);
  root.position.set(origin[0] - stand[0], tableHeight, origin[1] + stand[1]);
  root.userData = { tableHeight, stand: [...stand], origin: [...origin] };
  root.updateMatrixWorld(true);
}

/** A three.js-space position as a world [x, y, z]. */
export function toWorldPosition(root, v) {
  const p = root.worldToLocal(v.clone());
  return [p.x, p.y, p.z];
}

/** A three.js-space orientation as a world quaternion [x, y, z, w]: the same rotation expressed
 * in the world's axes (an identity controller, pointing forward, is an identity hand: palm
 * down, fingers +y; an identity camera is a head looking +y). */
export function toWorldQuaternion(q) {
  const w = Q_WORLD_INV.clone().multiply(q).multiply(Q_WORLD);
  return [w.x, w.y, w.z, w.w];
}

/** A world quaternion about z by `yawRad` as [x, y, z, w]. */
export function yawQuat(yawRad) {
  return [0, 0, Math.sin(yawRad / 2), Math.cos(yawRad / 2)];
}

export function setPose(obj, p, q) {
  if (p) obj.position.set(p[0], p[1], p[2]);
  if (q) obj.quaternion.set(q[0], q[1], q[2], q[3]);
}
