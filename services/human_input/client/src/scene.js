// The world the participant sees, built from the bridge's `scene` message and updated by its
// `frame`s: floor, tables, board, parts with their kind, targets, cues, hands. Every fact (sizes,
// colours, positions, texts) comes from the bridge; nothing of a scenario is written here.
import * as THREE from 'three';
import { setPose } from './frames.js';
import { Batch, PartsView, litMaterial, outlineBars } from './batch.js';
import { handGeometry } from './hand-model.js';

const FLASH_HZ = 2; // a lit cue blinks: on for the first half of each period
const TABLE_COLORS = { human: '#8c7359' };
const OTHER_TABLE_COLOR = '#80808c';
const BOARD_COLOR = '#1f7336';
const FLOOR_COLOR = '#5a5e66';

export function flashOn(nowMs) {
  return Math.floor((nowMs / 1000) * FLASH_HZ * 2) % 2 === 0;
}

/** A canvas texture with one or more lines of text (labels of parts, "Waiting..", status). */
export function textTexture(lines, { fg = '#111', bg = 'rgba(255,255,255,0.85)', px = 48 } = {}) {
  const canvas = document.createElement('canvas');
  const ctx = canvas.getContext('2d');
  ctx.font = `bold ${px}px sans-serif`;
  const width = Math.max(...lines.map((l) => ctx.measureText(l).width)) + px;
  canvas.width = Math.ceil(width);
  canvas.height = Math.ceil(lines.length * px * 1.25 + px * 0.4);
  ctx.font = `bold ${px}px sans-serif`;
  if (bg) {
    ctx.fillStyle = bg;
    ctx.beginPath();
    ctx.roundRect(0, 0, canvas.width, canvas.height, px * 0.3);
    ctx.fill();
  }
  ctx.fillStyle = fg;
  ctx.textBaseline = 'top';
  lines.forEach((l, i) => ctx.fillText(l, px / 2, px * 0.3 + i * px * 1.25));
  const tex = new THREE.CanvasTexture(canvas);
  tex.colorSpace = THREE.SRGBColorSpace;
  // emFraction: the font's em as a share of the texture's height (for its angular size)
  return { tex, aspect: canvas.width / canvas.height, emFraction: px / canvas.height };
}

/** A sprite `height` metres tall showing `lines`, always facing the viewer. */
export function labelSprite(lines, height, opts) {
  const { tex, aspect, emFraction } = textTexture(lines, opts);
  const mat = new THREE.SpriteMaterial({ map: tex, depthTest: false, transparent: true });
  const s = new THREE.Sprite(mat);
  s.scale.set(height * aspect, height, 1);
  s.renderOrder = 10;
  s.userData.emFraction = emFraction;
  return s;
}

function box(size, color, opts = {}) {
  const m = new THREE.Mesh(
    new THREE.BoxGeometry(size[0], size[1], size[2]),
    litMaterial({ color, ...opts }),
  );
  return m;
}

/** A rectangle outline (a part's footprint) lying flat, `size` x/y. */
function outline(size, color, width = 0.004) {
  const g = new THREE.Group();
  const [sx, sy] = size;
  // a marking on a surface: pulled toward the viewer in depth more than the board (see
  // buildFurniture), so it always shows on the surface it lies on
  const mat = new THREE.MeshBasicMaterial({
    color,
    polygonOffset: true,
    polygonOffsetFactor: -4,
    polygonOffsetUnits: -4,
  });
  for (const [w, h, x, y] of outlineBars(sx, sy, width)) {
    const bar = new THREE.Mesh(new THREE.PlaneGeometry(w, h), mat);
    bar.position.set(x, y, 0);
    g.add(bar);
  }
  return g;
}

function yawed(obj, yawDeg) {
  obj.rotation.set(0, 0, THREE.MathUtils.degToRad(yawDeg || 0));
  return obj;
}

// the participant's target outlines and the workspace marking: drawn over the surface they lie
// on (see buildFurniture), unlit
function markingMaterial() {
  return new THREE.MeshBasicMaterial({ polygonOffset: true, polygonOffsetFactor: -4, polygonOffsetUnits: -4 });
}

/** Whose label a participant wants to see: the part to take next (the participant's one
 * grabbable now) and a part on its way (in a hand or a robot's gripper). Parts lying in a row on
 * a table or placed stay unlabelled, so labels never pile up and overlap. */
function labelShown(part) {
  if (part.placed) return false;
  if (part.holder) return true;
  return part.spec.owner === 'human' && part.grabbable !== false;
}

export class World {
  constructor(root) {
    this.root = root;
    this.group = new THREE.Group();
    root.add(this.group);
    this.parts = new Map(); // id -> {mesh (a pose, drawn by partsView), label, spec, holder, placed}
    this.partsView = new PartsView(this.group);
    this.targetNames = new Map(); // the participant's part id -> the name at its target
    this.goal = null; // a robot's target shown after a collision: {part, obj}
    this.cues = new Map(); // id -> {spec, obj, on, flashing}
    this.cueOn = new Map();
    this.hands = {};
    this.scene = null;
  }

  clear() {
    this.root.remove(this.group);
    this.partsView.dispose();
    for (const h of Object.values(this.hands)) {
      for (const shape of Object.values(h.palm.userData.shapes)) shape.dispose();
    }
    this.group.traverse((o) => {
      o.geometry?.dispose?.();
      o.material?.map?.dispose?.();
      o.material?.dispose?.();
    });
    this.group = new THREE.Group();
    this.root.add(this.group);
    this.partsView = new PartsView(this.group);
    this.furniture = null;
    this.parts.clear();
    this.targetNames.clear();
    this.cues.clear();
    this.hands = {};
    this.goal = null;
  }

  build(scene) {
    this.clear();
    this.scene = scene;
    this.buildFurniture();
    const g = this.group;
    const marks = new Batch();
    for (const e of scene.envelope || []) {
      // the robots' workspace: a faint floor marking only, not a wall in the view
      const size = [e.max[0] - e.min[0], e.max[1] - e.min[1]];
      marks.outline(size, '#a9b0a0', 0.002, [(e.max[0] + e.min[0]) / 2, (e.max[1] + e.min[1]) / 2, 0.0015]);
    }
    for (const p of scene.parts || []) {
      // the participant's targets are always marked on the board (named by addPart)
      if (p.owner === 'human' && p.target) {
        marks.outline(p.size, '#e8e8e8', 0.006, [p.target.xyz[0], p.target.xyz[1], 0.002], p.target.yaw_deg);
      }
    }
    this.markings = marks.mesh(markingMaterial());
    if (this.markings) {
      this.markings.name = 'markings';
      g.add(this.markings);
    }
    for (const p of scene.parts || []) this.addPart(p);
    for (const c of scene.cues || []) this.addCue(c);
    const handColor = scene.hand_color || '#3a7bff';
    for (const h of ['left', 'right']) {
      const shapes = { open: handGeometry(h, false), closed: handGeometry(h, true) };
      const palm = new THREE.Mesh(
        shapes.open,
        litMaterial({ color: handColor }),
      );
      palm.userData.shapes = shapes;
      const hand = new THREE.Group();
      hand.add(palm);
      hand.name = `hand:${h}`;
      hand.visible = false;
      g.add(hand);
      // a plumb line and a ring on the surface below the hand: depth is hard to judge on a
      // screen (and helps in a headset too)
      const plumb = new THREE.Mesh(
        new THREE.CylinderGeometry(0.0015, 0.0015, 1, 6),
        new THREE.MeshBasicMaterial({ color: handColor, transparent: true, opacity: 0.6 }),
      );
      plumb.rotation.x = Math.PI / 2;
      const ring = new THREE.Mesh(
        new THREE.RingGeometry(0.012, 0.018, 24),
        new THREE.MeshBasicMaterial({ color: handColor, depthTest: false, transparent: true }),
      );
      ring.renderOrder = 5;
      plumb.name = `plumb:${h}`;
      ring.name = `ring:${h}`;
      g.add(plumb, ring);
      this.hands[h] = { obj: hand, palm, grip: 0, plumb, ring };
    }
  }

  /** Floor, tables (with legs to the floor) and board; again after a calibration, which moves
   * the floor (the one under the participant's feet, not the physics floor: in a headset the
   * drawn floor must agree with the real one). */
  buildFurniture() {
    const scene = this.scene;
    if (this.furniture) {
      this.group.remove(this.furniture);
      this.furniture.traverse((o) => {
        o.geometry?.dispose?.();
        o.material?.dispose?.();
      });
    }
    const g = new THREE.Group();
    this.furniture = g;
    this.group.add(g);
    const floorZ = -(this.root.userData.tableHeight ?? -(scene.floor_z ?? -0.75));
    // floor, tables and legs never move: one mesh, one draw call
    const still = new Batch();
    still.add(new THREE.PlaneGeometry(8, 8), FLOOR_COLOR, new THREE.Matrix4().makeTranslation(0, 0, floorZ));
    for (const t of scene.tables || []) {
      still.box(t.size, t.color || TABLE_COLORS[t.id] || OTHER_TABLE_COLOR, t.center);
      const legH = t.center[2] - t.size[2] / 2 - floorZ;
      if (legH > 0.05) {
        for (const sx of [-1, 1])
          for (const sy of [-1, 1]) {
            still.box([0.04, 0.04, legH], '#555', [
              t.center[0] + sx * (t.size[0] / 2 - 0.03),
              t.center[1] + sy * (t.size[1] / 2 - 0.03),
              t.center[2] - t.size[2] / 2 - legH / 2,
            ]);
          }
      }
    }
    const furniture = still.mesh(litMaterial());
    furniture.name = 'furniture';
    g.add(furniture);
    if (scene.board) {
      // The board's top is flush with the table top around it (the same plane, z = 0): drawn
      // pulled toward the viewer in depth, it wins that tie in every view (without it the
      // table's brown showed through at some view angles and aspect ratios).
      const b = box(scene.board.size, scene.board.color || BOARD_COLOR, {
        polygonOffset: true,
        polygonOffsetFactor: -2,
        polygonOffsetUnits: -2,
      });
      setPose(b, scene.board.center);
      b.name = 'board';
      g.add(b);
    }
  }

  addPart(p) {
    const mesh = new THREE.Object3D(); // the part's pose: partsView draws it
    mesh.name = `part:${p.id}`;
    const label = labelSprite([p.kind || p.id], 0.028, { px: 40 });
    label.name = `label:${p.id}`;
    label.position.set(0, 0, p.size[2] / 2 + 0.018);
    this.group.add(label);
    if (p.start) {
      setPose(mesh, p.start.xyz);
      yawed(mesh, p.start.yaw_deg);
    } else {
      mesh.visible = false; // spawned later (screws): shown once a frame carries it
    }
    label.visible = mesh.visible;
    this.group.add(mesh);
    this.parts.set(p.id, { mesh, label, spec: p, holder: '', placed: false });
    if (p.owner === 'human' && p.target) {
      // the part's name at its target (the outline is one of the markings)
      const name = labelSprite([p.id], 0.03, { px: 40, bg: 'rgba(30,30,30,0.75)', fg: '#f4f4f4' });
      // hung from just before the near edge of the target's cue (1.3 x the part), on the
      // board, downwards on screen: a name drawn over everything must not cover its target nor
      // a robot's cue on it (a screw hole), whatever the eye's height (a centred name, or one
      // hung from above the board, covered the hole from a seated eye)
      name.center.set(0.5, 1);
      name.position.set(p.target.xyz[0], p.target.xyz[1] - 0.65 * p.size[1] - 0.006, 0.003);
      name.renderOrder = 9;
      name.name = `target-name:${p.id}`;
      this.group.add(name);
      this.targetNames.set(p.id, name);
    }
  }

  addCue(c) {
    let obj;
    const color = c.color || '#ffffff';
    const part = c.part ? (this.scene.parts || []).find((p) => p.id === c.part) : null;
    if (c.kind === 'target' && part) {
      // a plane in the robot's (or the participant's) colour over the target footprint
      // drawn over whatever sits on the target (a mounting plate): a cue is never hidden
      obj = new THREE.Mesh(
        new THREE.PlaneGeometry(part.size[0] * 1.3, part.size[1] * 1.3),
        new THREE.MeshBasicMaterial({
          color, transparent: true, opacity: 0.9, depthWrite: false, depthTest: false,
        }),
      );
      obj.renderOrder = 6;
      setPose(obj, [c.position[0], c.position[1], 0.003]);
      yawed(obj, part.target?.yaw_deg);
    } else if (c.kind === 'outline' && part) {
      obj = outline([part.size[0] * 1.3, part.size[1] * 1.3], color, 0.006);
      obj.userData.followPart = c.part;
      obj.userData.outlineSize = [part.size[0] * 1.3, part.size[1] * 1.3];
    } else if (c.kind === 'waiting') {
      obj = labelSprite([c.text || 'Waiting..'], 0.07, { fg: color, bg: 'rgba(20,20,20,0.8)' });
      setPose(obj, c.position);
      obj.userData.anchor = [...c.position]; // where it stands unless a box would cover it
    } else if (c.kind === 'button' && this.scene.safety_policy !== 'retreat_button') {
      return; // only the retreat_button policy uses the continue button
    } else if (c.kind === 'button') {
      obj = new THREE.Group();
      const base = new THREE.Mesh(
        new THREE.CylinderGeometry(0.045, 0.045, 0.01, 32),
        litMaterial({ color: '#444' }),
      );
      base.rotation.x = Math.PI / 2;
      const cap = new THREE.Mesh(
        new THREE.CylinderGeometry(0.035, 0.035, 0.02, 32),
        new THREE.MeshBasicMaterial({ color }),
      );
      cap.rotation.x = Math.PI / 2;
      cap.position.z = 0.01;
      obj.add(base, cap);
      obj.userData.cap = cap;
      obj.userData.offColor = new THREE.Color('#777');
      const label = labelSprite(['continue'], 0.025, { px: 36 });
      label.position.z = 0.05;
      obj.add(label);
      setPose(obj, c.position);
    } else {
      obj = labelSprite([c.text || c.id], 0.03);
      setPose(obj, c.position);
    }
    obj.name = `cue:${c.id}`;
    const alwaysShown = c.kind === 'button';
    obj.visible = alwaysShown;
    this.group.add(obj);
    this.cues.set(c.id, { spec: c, obj, on: false, alwaysShown, color: new THREE.Color(color) });
  }

  /** After a collision: the target of the part the robot carries, in its colour, with its name,
   * over everything (part '' hides it). */
  showGoal(part, robot) {
    if (this.goal && this.goal.part === part) return;
    if (this.goal) {
      this.group.remove(this.goal.obj);
      this.goal.obj.traverse((o) => {
        o.geometry?.dispose?.();
        o.material?.map?.dispose?.();
        o.material?.dispose?.();
      });
      this.goal = null;
    }
    const spec = part && this.parts.get(part)?.spec;
    if (!spec) return;
    const color = (this.scene.robots || []).find((r) => r.id === robot)?.color || spec.color;
    const obj = outline([spec.size[0] * 1.6, spec.size[1] * 1.6], color, 0.008);
    obj.traverse((o) => {
      if (o.material) o.material.depthTest = false;
      o.renderOrder = 7;
    });
    setPose(obj, [spec.target.xyz[0], spec.target.xyz[1], 0.004]);
    yawed(obj, spec.target.yaw_deg);
    const name = labelSprite([`${robot} \u2192 ${part}`], 0.028, { fg: color, bg: 'rgba(20,20,20,0.85)' });
    name.position.set(0, 0, 0.06);
    obj.add(name);
    obj.name = 'goal';
    this.group.add(obj);
    this.goal = { part, obj };
  }

  /** The "Waiting.." labels say for what (text('') keeps the scene's text). */
  updateWaitingTexts(text) {
    for (const cue of this.cues.values()) {
      if (cue.spec.kind !== 'waiting' || !cue.on) continue;
      const want = text(cue.spec.robot) || cue.spec.text || 'Waiting..';
      if (cue.obj.userData.text === want) continue;
      cue.obj.userData.text = want;
      const { tex, aspect } = textTexture([want], { fg: cue.spec.color || '#fff', bg: 'rgba(20,20,20,0.8)' });
      cue.obj.material.map.dispose();
      cue.obj.material.map = tex;
      cue.obj.scale.set(0.07 * aspect, 0.07, 1);
    }
  }

  applyFrame(f) {
    for (const [id, o] of Object.entries(f.objects || {})) {
      let part = this.parts.get(id);
      if (!part) {
        this.addPart({ id, kind: id, size: [0.02, 0.02, 0.02], color: '#aaaaaa', start: null });
        part = this.parts.get(id);
      }
      if (o.p) {
        setPose(part.mesh, o.p, o.q);
        part.mesh.visible = true;
        part.label.visible = true;
      }
      if (o.holder !== undefined) part.holder = o.holder;
      if (o.placed !== undefined) part.placed = o.placed;
      if (o.grabbable !== undefined) part.grabbable = o.grabbable;
    }
    // a lit cue whose live definition differs from the scene's (an outline where its part is
    // now, ...): outlines follow their part anyway; the others move to the new position
    for (const [id, def] of Object.entries(f.cue_defs || {})) {
      const cue = this.cues.get(id);
      if (!cue || !def.position || cue.obj.userData.followPart) continue;
      const [x, y, z] = def.position;
      cue.obj.position.set(x, y, cue.spec.kind === 'target' ? cue.obj.position.z : z);
    }
    for (const [id, v] of Object.entries(f.cues || {})) {
      const cue = this.cues.get(id);
      if (!cue) continue;
      // a cue is `true`/`false`, or its definition with `on` when it moved (an outline)
      if (v !== null && typeof v === 'object') {
        cue.on = !!v.on;
        if (v.position && cue.spec.kind === 'waiting') {
          setPose(cue.obj, v.position);
          cue.obj.userData.anchor = [...v.position];
        }
      } else {
        cue.on = !!v;
      }
    }
  }

  /** Per rendered frame: labels follow parts, cues blink, outlines follow their part. A test
   * may hold the blink lit or unlit (`flashHeld`: true / false; null: it blinks). */
  animate(nowMs) {
    const lit = this.flashHeld ?? flashOn(nowMs);
    for (const part of this.parts.values()) {
      const m = part.mesh;
      // a label above its part; under it while a robot carries it (the gripper is above)
      const byRobot = part.holder && part.holder !== 'left' && part.holder !== 'right';
      const dz = (part.spec.size[2] / 2 + 0.018) * (byRobot ? -1 : 1);
      part.label.position.set(m.position.x, m.position.y, m.position.z + dz);
      part.label.visible = m.visible && labelShown(part);
      const name = this.targetNames.get(part.spec.id);
      if (name) name.visible = !part.placed;
    }
    for (const cue of this.cues.values()) {
      const { spec, obj } = cue;
      if (spec.kind === 'button') {
        const cap = obj.userData.cap;
        cap.material.color.copy(cue.on && lit ? cue.color : obj.userData.offColor);
        continue;
      }
      if (spec.kind === 'waiting') {
        obj.visible = cue.on;
        continue;
      }
      obj.visible = cue.on && lit;
      if (obj.userData.followPart) {
        const p = this.parts.get(obj.userData.followPart);
        if (p) {
          obj.position.set(p.mesh.position.x, p.mesh.position.y, 0.003);
          obj.rotation.set(0, 0, new THREE.Euler().setFromQuaternion(p.mesh.quaternion, 'ZYX').z);
        }
      }
    }
    this.partsView.sync([...this.parts.values()]);
  }

  setHand(name, p, q, grip) {
    const h = this.hands[name];
    if (!h) return;
    h.obj.visible = true;
    setPose(h.obj, p, q);
    const floorZ = 0.002; // the board's and table's top
    const len = Math.max(0.001, p[2] - floorZ);
    h.plumb.scale.set(1, len, 1);
    h.plumb.position.set(p[0], p[1], floorZ + len / 2);
    h.ring.position.set(p[0], p[1], floorZ);
    h.grip = grip;
    // a closed hand: fingers curled under the palm, a little lighter
    const shapes = h.palm.userData.shapes;
    h.palm.geometry = grip >= 0.5 ? shapes.closed : shapes.open;
    h.palm.material.emissive?.setRGB(grip >= 0.5 ? 0.1 : 0, grip >= 0.5 ? 0.1 : 0, 0);
  }

  /** The part held by a hand follows the local hand at once (the frame's pose lags by a round
   * trip): its offset to the hand is taken when the grab is first seen. */
  followHands(local) {
    for (const part of this.parts.values()) {
      const h = local[part.holder];
      if (!h) {
        part.offset = null;
        continue;
      }
      const hm = new THREE.Matrix4().compose(
        new THREE.Vector3(...h.p),
        new THREE.Quaternion(...h.q),
        new THREE.Vector3(1, 1, 1),
      );
      if (!part.offset) {
        part.mesh.updateMatrix();
        part.offset = hm.clone().invert().multiply(part.mesh.matrix);
      }
      const m = hm.multiply(part.offset);
      m.decompose(part.mesh.position, part.mesh.quaternion, new THREE.Vector3());
    }
  }
}
