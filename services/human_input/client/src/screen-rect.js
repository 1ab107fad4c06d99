// Where a sprite (a label facing the camera) lies on the page, in CSS pixels: the desktop page
// keeps its "Waiting.." labels clear of its boxes (main.js), and the tests check that no label
// covers another (test-hooks.js).
import * as THREE from 'three';

/** The sprite's rectangle {x0, y0, x1, y1} as `camera` draws it on `canvas`. */
export function spriteRect(camera, canvas, sprite) {
  const rect = canvas.getBoundingClientRect();
  const right = new THREE.Vector3().setFromMatrixColumn(camera.matrixWorld, 0);
  const up = new THREE.Vector3().setFromMatrixColumn(camera.matrixWorld, 1);
  const c = sprite.getWorldPosition(new THREE.Vector3());
  const s = sprite.getWorldScale(new THREE.Vector3());
  const xs = [];
  const ys = [];
  for (const [a, b] of [[-1, -1], [1, -1], [1, 1], [-1, 1]]) {
    const w = c.clone().addScaledVector(right, (a * s.x) / 2).addScaledVector(up, (b * s.y) / 2);
    w.project(camera);
    xs.push(rect.left + ((w.x + 1) / 2) * rect.width);
    ys.push(rect.top + ((1 - w.y) / 2) * rect.height);
  }
  return { x0: Math.min(...xs), y0: Math.min(...ys), x1: Math.max(...xs), y1: Math.max(...ys) };
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
