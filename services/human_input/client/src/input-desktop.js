// Desktop mode: a 3D view from the participant's standpoint; the mouse and keys move the active
// hand (x/y with the mouse on the plane at the hand's height or the arrow keys, height with the
// wheel or W/S, yaw with Q/E, grip with Space/G or a click) and switch hands (Tab/H).
// After a release (and after R) the hand goes back to rest beside the body and stays there: it
// is "parked" until the mouse is moved on purpose (PARK_PX from where it was) or a key moves it,
// so a hand that has just placed a part never lingers where a robot is about to come.
import * as THREE from 'three';
import { toWorldQuaternion, yawQuat } from './frames.js';

// where a hand rests when it is not used: beside the body, outside the robots' workspace
const REST = { left: [-0.22, -0.56, 0.1], right: [0.22, -0.56, 0.1] };
const STEP_M = 0.01;
const BIG_STEP_M = 0.05; // with Shift
const PARK_PX = 60; // the mouse takes a parked hand back after moving this far
const YAW_STEP_DEG = 15;
const Z_MIN = 0.0;
const Z_MAX = 0.6;
const REACH_M = 1.5;
const HEAD_Z = 0.6; // eye height above the board (a standing person at a table) // how far from the board centre the mouse may take a hand

export const KEY_HELP = [
  'mouse: move the active hand (x/y)',
  'wheel or W/S: hand height',
  'arrows: move the hand 1 cm (Shift: 5 cm)',
  'Q/E: turn the hand 15\u00b0',
  'Space, G or click: close/open the grip',
  'opening the grip puts the hand back to rest;',
  '  move the mouse a little to take it again',
  'Tab or H: switch hand, R: hand to rest',
  'V: participant view / top view, F1: this help',
];

export class DesktopInput {
  constructor({ canvas, camera, root, sendNow }) {
    this.canvas = canvas;
    this.camera = camera;
    this.root = root;
    this.sendNow = sendNow; // sends the hands at once (the bridge keeps each grip change a tick)
    this.active = 'right';
    this.view = 'participant';
    this.hands = {
      left: { p: [...REST.left], yawDeg: 0, grip: 0 },
      right: { p: [...REST.right], yawDeg: 0, grip: 0 },
    };
    this.enabled = false;
    this.parked = null; // {x, y}: the pointer when the hand went to rest; null: it follows
    this.raycaster = new THREE.Raycaster();
    this.bindings = [];
  }

  on(target, ev, fn, opts) {
    target.addEventListener(ev, fn, opts);
    this.bindings.push([target, ev, fn, opts]);
  }

  enable() {
    if (this.enabled) return;
    this.enabled = true;
    this.on(this.canvas, 'mousemove', (e) => this.mouseMove(e));
    this.on(this.canvas, 'mousedown', (e) => {
      if (e.button === 0) this.toggleGrip();
    });
    this.on(this.canvas, 'wheel', (e) => {
      e.preventDefault();
      this.moveBy(0, 0, e.deltaY < 0 ? STEP_M : -STEP_M);
    }, { passive: false });
    this.on(window, 'keydown', (e) => this.key(e));
    this.placeCamera();
  }

  disable() {
    for (const [t, ev, fn, opts] of this.bindings) t.removeEventListener(ev, fn, opts);
    this.bindings = [];
    this.enabled = false;
  }

  hand() {
    return this.hands[this.active];
  }

  /** The camera a little behind and above the participant's eyes (so the hands, the board and
   * both robots are in view at once), or straight above the board. */
  placeCamera() {
    const eye = new THREE.Vector3();
    const look = new THREE.Vector3();
    const stand = this.root.userData.stand || [0, -0.7];
    if (this.view === 'top') {
      eye.set(stand[0], 0.0, 1.45);
      look.set(stand[0], 0.0, 0);
    } else {
      eye.set(stand[0], stand[1] - 0.3, 0.8);
      look.set(stand[0], stand[1] + 0.9, 0.0);
    }
    this.root.localToWorld(eye);
    this.root.localToWorld(look);
    this.camera.position.copy(eye);
    if (this.view === 'top') {
      // +y of the world points up on the screen
      this.camera.up.copy(new THREE.Vector3(0, 0, -1));
    } else {
      this.camera.up.set(0, 1, 0);
    }
    this.camera.lookAt(look);
    this.camera.updateMatrixWorld(true);
  }

  /** The active hand back to rest, where it stays until the person takes it again. */
  park() {
    this.hand().p = [...REST[this.active]];
    this.hand().yawDeg = 0;
    this.parked = this.lastPointer ? { ...this.lastPointer } : { x: -1e9, y: -1e9 };
  }

  mouseMove(e) {
    this.lastPointer = { x: e.clientX, y: e.clientY };
    if (this.parked) {
      if (Math.hypot(e.clientX - this.parked.x, e.clientY - this.parked.y) < PARK_PX) return;
      this.parked = null;
    }
    const rect = this.canvas.getBoundingClientRect();
    const ndc = new THREE.Vector2(
      ((e.clientX - rect.left) / rect.width) * 2 - 1,
      -((e.clientY - rect.top) / rect.height) * 2 + 1,
    );
    this.raycaster.setFromCamera(ndc, this.camera);
    // the horizontal plane at the hand's height, in three.js space
    const h = this.hand();
    const onPlane = new THREE.Vector3(0, 0, h.p[2]);
    this.root.localToWorld(onPlane);
    const plane = new THREE.Plane(new THREE.Vector3(0, 1, 0), -onPlane.y);
    const hit = new THREE.Vector3();
    if (!this.raycaster.ray.intersectPlane(plane, hit)) return;
    this.root.worldToLocal(hit);
    if (Math.hypot(hit.x, hit.y) > REACH_M) return;
    h.p[0] = hit.x;
    h.p[1] = hit.y;
  }

  moveBy(dx, dy, dz) {
    this.parked = null;
    const h = this.hand();
    h.p[0] += dx;
    h.p[1] += dy;
    h.p[2] = Math.min(Z_MAX, Math.max(Z_MIN, h.p[2] + dz));
  }

  toggleGrip() {
    const h = this.hand();
    const release = h.grip >= 0.5;
    h.grip = release ? 0 : 1;
    if (release) {
      // The release goes out with the hand where it is, and the hand goes to rest at once
      // after it: a robot due at the part the person just let go of meets no hand there (the
      // bridge keeps every grip change for a tick, so the part is let go where it was put).
      this.sendNow?.();
      this.park();
      this.sendNow?.();
    }
  }

  /** A page that becomes the driver starts with both grips open; true if one was closed. */
  releaseGrips() {
    const held = Object.values(this.hands).some((h) => h.grip >= 0.5);
    for (const h of Object.values(this.hands)) h.grip = 0;
    return held;
  }

  key(e) {
    if (e.target && e.target.tagName === 'INPUT') return;
    const k = e.key.length === 1 ? e.key.toLowerCase() : e.key;
    const step = e.shiftKey ? BIG_STEP_M : STEP_M;
    let handled = true;
    switch (k) {
      case 'ArrowLeft': this.moveBy(-step, 0, 0); break;
      case 'ArrowRight': this.moveBy(step, 0, 0); break;
      case 'ArrowUp': this.moveBy(0, step, 0); break;
      case 'ArrowDown': this.moveBy(0, -step, 0); break;
      case 'w': case 'PageUp': this.moveBy(0, 0, step); break;
      case 's': case 'PageDown': this.moveBy(0, 0, -step); break;
      case 'q': this.hand().yawDeg += YAW_STEP_DEG; break;
      case 'e': this.hand().yawDeg -= YAW_STEP_DEG; break;
      case ' ': case 'g': this.toggleGrip(); break;
      case 'Tab': case 'h':
        this.active = this.active === 'right' ? 'left' : 'right';
        break;
      case 'r':
        this.park();
        break;
      case 'v':
        this.view = this.view === 'top' ? 'participant' : 'top';
        this.placeCamera();
        break;
      default:
        handled = false;
    }
    if (handled) e.preventDefault();
  }

  /** The hands as the world sees them: {left: {p, q, grip}, right: ...}. */
  poses() {
    const out = {};
    for (const [name, h] of Object.entries(this.hands)) {
      out[name] = { p: [...h.p], q: yawQuat(THREE.MathUtils.degToRad(h.yawDeg)), grip: h.grip };
    }
    return out;
  }

  /** The participant's sample (docs/replay-format.md shape). The head is at the standing
   * point at eye height, looking where the camera looks. */
  sample() {
    const stand = this.root.userData.stand || [0, -0.7];
    const hp = new THREE.Vector3(stand[0], stand[1], HEAD_Z);
    const hq = new THREE.Quaternion();
    this.camera.getWorldQuaternion(hq);
    const poses = this.poses();
    return {
      head: { position: [hp.x, hp.y, hp.z], orientation: toWorldQuaternion(this.root, hq) },
      left: { position: poses.left.p, orientation: poses.left.q },
      right: { position: poses.right.p, orientation: poses.right.q },
      left_grip: poses.left.grip,
      right_grip: poses.right.grip,
    };
  }

  statusLine() {
    const h = this.hand();
    const f = (v) => v.toFixed(2);
    return `${this.active} hand (${f(h.p[0])}, ${f(h.p[1])}, ${f(h.p[2])}) yaw ${h.yawDeg}\u00b0 ` +
      `grip ${h.grip >= 0.5 ? 'closed' : 'open'}` +
      (this.parked ? ' - at rest: move the mouse to take it' : '');
  }
}
