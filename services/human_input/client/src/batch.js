// Fewer draw calls (a headset's budget is about 100 per frame): static things of one kind are
// merged into one mesh with a colour per vertex, and the parts are one instanced mesh.
import * as THREE from 'three';
import { mergeGeometries } from 'three/addons/utils/BufferGeometryUtils.js';

/** The material of every lit (shaded) thing: Lambert's diffuse shading. The matte colours here
 * look the same as with three.js's physically based one (MeshStandardMaterial, which they used
 * until 2026-12-02), at about half its cost per pixel: where WebGL is drawn by the CPU
 * (SwiftShader: the browser tests, an experimenter's machine without a GPU) a 1280 x 800 frame
 * of the thesis scene takes 64 instead of 103 ms of the GPU process's CPU, and a headset's
 * mobile GPU is bound by its pixels too. */
export function litMaterial(params = {}) {
  return new THREE.MeshLambertMaterial(params);
}

/** `geometry` with a `color` attribute: `color` (a THREE.Color or a CSS colour) at every
 * vertex, so that pieces of several colours merge into one mesh. */
export function painted(geometry, color) {
  const c = color instanceof THREE.Color ? color : new THREE.Color(color);
  const n = geometry.attributes.position.count;
  const rgb = new Float32Array(n * 3);
  for (let i = 0; i < n; i++) rgb.set([c.r, c.g, c.b], i * 3);
  geometry.setAttribute('color', new THREE.BufferAttribute(rgb, 3));
  return geometry;
}

/** Collects geometries (each with its colour and pose) and makes one mesh of them. */
export class Batch {
  constructor() {
    this.pieces = [];
  }

  /** `geometry` (consumed) placed by `matrix`, painted `color`. */
  add(geometry, color, matrix) {
    const g = geometry; // every piece is indexed (Box/Plane/Cylinder geometries): they merge
    g.deleteAttribute('uv');
    g.applyMatrix4(matrix);
    this.pieces.push(painted(g, color));
  }

  /** A box `size` at `center` (yaw about z in degrees). */
  box(size, color, center, yawDeg = 0) {
    const m = new THREE.Matrix4().compose(
      new THREE.Vector3(...center),
      new THREE.Quaternion().setFromAxisAngle(new THREE.Vector3(0, 0, 1), THREE.MathUtils.degToRad(yawDeg)),
      new THREE.Vector3(1, 1, 1),
    );
    this.add(new THREE.BoxGeometry(...size), color, m);
  }

  /** A rectangle's outline lying flat at `center` (x, y, z), inner size `size` (x, y). */
  outline(size, color, width, center, yawDeg = 0) {
    const [sx, sy] = size;
    const turn = new THREE.Matrix4().compose(
      new THREE.Vector3(...center),
      new THREE.Quaternion().setFromAxisAngle(new THREE.Vector3(0, 0, 1), THREE.MathUtils.degToRad(yawDeg)),
      new THREE.Vector3(1, 1, 1),
    );
    for (const [w, h, x, y] of outlineBars(sx, sy, width)) {
      const m = turn.clone().multiply(new THREE.Matrix4().makeTranslation(x, y, 0));
      this.add(new THREE.PlaneGeometry(w, h), color, m);
    }
  }

  /** The merged mesh (null if nothing was added). */
  mesh(material) {
    if (!this.pieces.length) return null;
    const merged = mergeGeometries(this.pieces, false);
    for (const p of this.pieces) p.dispose();
    this.pieces = [];
    material.vertexColors = true;
    return new THREE.Mesh(merged, material);
  }
}

/** The four bars of a rectangle outline: [w, h, x, y] each. */
export function outlineBars(sx, sy, width) {
  return [
    [sx + width, width, 0, sy / 2],
    [sx + width, width, 0, -sy / 2],
    [width, sy + width, sx / 2, 0],
    [width, sy + width, -sx / 2, 0],
  ];
}

// the twelve edges of a unit cube centred at the origin, as line segment end points
const CUBE_EDGES = (() => {
  const out = [];
  const c = [-0.5, 0.5];
  for (const a of c) for (const b of c) {
    out.push([-0.5, a, b], [0.5, a, b]);
    out.push([a, -0.5, b], [a, 0.5, b]);
    out.push([a, b, -0.5], [a, b, 0.5]);
  }
  return out.map((p) => new THREE.Vector3(...p));
})();

/** Every part as one instance of a unit box (scaled to its size, in its colour) and all their
 * edges as one set of lines: two draw calls however many parts. The parts' poses stay on plain
 * Object3Ds (`part.mesh`), copied here once per rendered frame. */
export class PartsView {
  constructor(group) {
    this.group = group;
    this.boxes = null;
    this.edges = null;
    this.capacity = 0;
    this.hidden = new THREE.Matrix4().makeScale(0, 0, 0);
    this.last = null; // the poses last copied (7 numbers a part, NaN hidden): unchanged, no copy
    this.m = new THREE.Matrix4();
    this.s = new THREE.Vector3();
    this.v = new THREE.Vector3();
    this.color = new THREE.Color();
  }

  /** (Re)makes the meshes for `n` parts (a new part past the capacity rebuilds them). */
  ensure(n) {
    if (this.boxes && n <= this.capacity) return;
    this.last = null;
    this.dispose();
    this.capacity = Math.max(n, 8) + 8;
    this.boxes = new THREE.InstancedMesh(
      new THREE.BoxGeometry(1, 1, 1),
      litMaterial(),
      this.capacity,
    );
    this.boxes.name = 'parts';
    this.boxes.frustumCulled = false; // the instances move: the unit box's bounds mean nothing
    const positions = new Float32Array(this.capacity * CUBE_EDGES.length * 3);
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.BufferAttribute(positions, 3));
    this.edges = new THREE.LineSegments(g, new THREE.LineBasicMaterial({ color: '#222' }));
    this.edges.name = 'part-edges';
    this.edges.frustumCulled = false;
    this.group.add(this.boxes, this.edges);
  }

  dispose() {
    this.last = null;
    for (const o of [this.boxes, this.edges]) {
      if (!o) continue;
      this.group.remove(o);
      o.geometry.dispose();
      o.material.dispose();
    }
    this.boxes = null;
    this.edges = null;
    this.capacity = 0;
  }

  /** Copies the parts' poses, sizes and colours (in the order of `parts`) to the GPU. */
  sync(parts) {
    this.ensure(parts.length);
    // most frames move no part (a robot waits, the hands are empty): those copy nothing
    const fresh = !this.last || this.last.length !== parts.length * 7; // new meshes: colours too
    if (fresh) this.last = new Float64Array(parts.length * 7);
    let same = !fresh;
    parts.forEach((p, i) => {
      const { position: t, quaternion: q } = p.mesh;
      const now = p.mesh.visible ? [t.x, t.y, t.z, q.x, q.y, q.z, q.w] : [NaN, 0, 0, 0, 0, 0, 0];
      for (let j = 0; j < 7; j++) {
        const old = this.last[i * 7 + j];
        if (old !== now[j] && !(Number.isNaN(old) && Number.isNaN(now[j]))) same = false;
        this.last[i * 7 + j] = now[j];
      }
    });
    if (same) return;
    const { m, s, v, color } = this;
    const pos = this.edges.geometry.attributes.position;
    let k = 0;
    parts.forEach((part, i) => {
      const o = part.mesh;
      if (o.visible) {
        s.set(...part.spec.size);
        m.compose(o.position, o.quaternion, s);
      } else {
        m.copy(this.hidden);
      }
      this.boxes.setMatrixAt(i, m);
      if (fresh) this.boxes.setColorAt(i, color.set(part.spec.color || '#aaaaaa'));
      for (const e of CUBE_EDGES) {
        v.copy(e).applyMatrix4(m);
        pos.setXYZ(k++, v.x, v.y, v.z);
      }
    });
    for (let i = parts.length; i < this.capacity; i++) this.boxes.setMatrixAt(i, this.hidden);
    this.boxes.count = parts.length;
    this.edges.geometry.setDrawRange(0, k);
    this.boxes.instanceMatrix.needsUpdate = true;
    if (fresh && this.boxes.instanceColor) this.boxes.instanceColor.needsUpdate = true;
    pos.needsUpdate = true;
  }
}
