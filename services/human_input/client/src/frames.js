// The scenario's world frame (z up, origin at the board's top centre, the participant at -y
// looking +y) inside three.js's (y up). Everything of the scene hangs under one root group whose
// pose is the calibration: the standing point (x, y on the floor), the table height and the yaw
// (the direction the participant faces the table).
import * as THREE from 'three';

// world -> three: (x, y, z) -> (x, z, -y), a rotation of -90 degrees about x
export const Q_WORLD = new THREE.Quaternion().setFromAxisAngle(new THREE.Vector3(1, 0, 0), -Math.PI / 2);

export const DEFAULT_TABLE_HEIGHT = 0.9; // board top above the floor, m
export const DEFAULT_STAND = [0.0, -0.7]; // where the participant stands (the XR origin), m

/** Poses the root group so that the floor point `origin` (XR x, z; the XR origin by default)
 * is at world (stand_x, stand_y, -table_height) and the world's +y (towards the robots) points
 * along the XR heading `yawRad` (0: XR -z; positive turns left, as three.js turns about +y):
 * three = R * world + t. */
export function placeRoot(root, tableHeight, stand, origin = [0, 0], yawRad = 0) {
  const turn = new THREE.Quaternion().setFromAxisAngle(new THREE.Vector3(0, 1, 0), yawRad);
  root.quaternion.copy(turn).multiply(Q_WORLD);
  // the stand point, as three.js sees it with the table top at y = 0, ends on the origin
  const standXr = new THREE.Vector3(stand[0], stand[1], 0).applyQuaternion(root.quaternion);
  root.position.set(origin[0] - standXr.x, tableHeight, origin[1] - standXr.z);
  root.userData = { tableHeight, stand: [...stand], origin: [...origin], yawRad };
  root.updateMatrixWorld(true);
}

/** A three.js-space position as a world [x, y, z]. */
export function toWorldPosition(root, v) {
  const p = root.worldToLocal(v.clone());
  return [p.x, p.y, p.z];
}

/** A three.js-space orientation as a world quaternion [x, y, z, w]: the same rotation expressed
 * in the world's axes (a controller pointing where the calibration's heading points is an
 * identity hand: palm down, fingers +y; so is a camera a head looking +y). */
export function toWorldQuaternion(root, q) {
  const w = root.quaternion.clone().invert().multiply(q).multiply(Q_WORLD);
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
