// Where a sprite (a label facing the camera) lies on the page, in CSS pixels: the desktop page
// keeps its "Waiting.." labels clear of its boxes, a headset keeps them clear of its panel
// (main.js), and the tests check that no label covers another (test-hooks.js).
import * as THREE from 'three';

/** The world corners of a sprite's quad as `camera` sees it (a sprite faces the camera). */
export function spriteCorners(camera, sprite) {
  const right = new THREE.Vector3().setFromMatrixColumn(camera.matrixWorld, 0);
  const up = new THREE.Vector3().setFromMatrixColumn(camera.matrixWorld, 1);
  const c = sprite.getWorldPosition(new THREE.Vector3());
  const s = sprite.getWorldScale(new THREE.Vector3());
  // the sprite's anchor (`center`, 0..1 of its size) sits at its position
  const { x: ax, y: ay } = sprite.center;
  return [[0, 0], [1, 0], [1, 1], [0, 1]].map(([a, b]) =>
    c.clone().addScaledVector(right, (a - ax) * s.x).addScaledVector(up, (b - ay) * s.y));
}

/** The world corners of a unit plane (PlaneGeometry(1, 1): the headset's panel). */
export function planeCorners(mesh) {
  return [[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]].map(([x, y]) =>
    mesh.localToWorld(new THREE.Vector3(x, y, 0)));
}

/** The rectangle {x0, y0, x1, y1} around `points` (world) in `camera`'s normalised device
 * coordinates (-1..1, y up): a headset's eyes have no page to measure in. */
export function ndcRect(camera, points) {
  const xs = [];
  const ys = [];
  for (const w of points) {
    const v = w.clone().project(camera);
    xs.push(v.x);
    ys.push(v.y);
  }
  return { x0: Math.min(...xs), y0: Math.min(...ys), x1: Math.max(...xs), y1: Math.max(...ys) };
}

/** The sprite's rectangle {x0, y0, x1, y1} as `camera` draws it on `canvas`. */
export function spriteRect(camera, canvas, sprite) {
  const rect = canvas.getBoundingClientRect();
  const n = ndcRect(camera, spriteCorners(camera, sprite));
  return {
    x0: rect.left + ((n.x0 + 1) / 2) * rect.width,
    y0: rect.top + ((1 - n.y1) / 2) * rect.height,
    x1: rect.left + ((n.x1 + 1) / 2) * rect.width,
    y1: rect.top + ((1 - n.y0) / 2) * rect.height,
  };
}

/** The page's boxes over the 3D view that are showing ({x0, y0, x1, y1}), by element id. */
export function pageBoxes(ids) {
  const out = {};
  for (const id of ids) {
    const e = document.getElementById(id);
    if (!e || getComputedStyle(e).display === 'none' || e.style.visibility === 'hidden') continue;
    const r = e.getBoundingClientRect();
    if (r.width > 0 && r.height > 0) out[id] = { x0: r.left, y0: r.top, x1: r.right, y1: r.bottom };
  }
  return out;
}

export function overlaps(a, b) {
  return a.x0 < b.x1 && b.x0 < a.x1 && a.y0 < b.y1 && b.y0 < a.y1;
}
