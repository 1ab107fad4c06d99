// Immersive mode: WebXR `immersive-vr` in the `local-floor` space. Each controller's grip pose
// drives its hand, squeeze or trigger (the larger) its grip; the headset is the head. The XR
// frame loop only reads poses and sends (never waits for the network). Calibration: the A/X
// button takes the table height from the right controller resting on the table top, and the
// standing point and the direction the participant faces (the head's heading) from the head.
import * as THREE from 'three';
import { toWorldPosition, toWorldQuaternion, yawQuat } from './frames.js';

export class XrInput {
  constructor({ renderer, root, onCalibrate }) {
    this.renderer = renderer;
    this.root = root;
    this.onCalibrate = onCalibrate;
    this.session = null;
    this.grips = [0, 1].map((i) => renderer.xr.getControllerGrip(i));
    this.sources = [null, null];
    this.calibrateHeld = false;
    this.grips.forEach((g, i) => {
      g.addEventListener('connected', (e) => { this.sources[i] = e.data; });
      g.addEventListener('disconnected', () => { this.sources[i] = null; });
    });
  }

  static async supported() {
    try {
      return !!navigator.xr && (await navigator.xr.isSessionSupported('immersive-vr'));
    } catch {
      return false;
    }
  }

  /** Must be called from a user gesture (a click on "Enter VR"). */
  async start(scene) {
    const session = await navigator.xr.requestSession('immersive-vr', {
      requiredFeatures: ['local-floor'],
    });
    this.renderer.xr.setReferenceSpaceType('local-floor');
    await this.renderer.xr.setSession(session);
    for (const g of this.grips) scene.add(g);
    this.session = session;
    session.addEventListener('end', () => { this.session = null; });
    return session;
  }

  active() {
    return !!this.session;
  }

  /** The hands from the controllers: {left: {p, q, grip}, right: ...}; a hand whose controller
   * is not tracked is left out. */
  hands() {
    const out = {};
    this.grips.forEach((g, i) => {
      const src = this.sources[i];
      if (!src || !src.handedness || src.handedness === 'none' || !g.visible) return;
      const p = new THREE.Vector3();
      const q = new THREE.Quaternion();
      g.getWorldPosition(p);
      g.getWorldQuaternion(q);
      const buttons = src.gamepad ? src.gamepad.buttons : [];
      const value = (b) => (b ? b.value || (b.pressed ? 1 : 0) : 0);
      // xr-standard mapping: 0 trigger, 1 squeeze, 4 A/X
      const grip = Math.max(value(buttons[0]), value(buttons[1]));
      const calib = value(buttons[4]) > 0.5;
      out[src.handedness] = {
        p: toWorldPosition(this.root, p),
        q: this.heading(q),
        grip: Math.min(1, Math.max(0, grip)),
        xr: p,
        calib,
      };
    });
    const pressed = Object.values(out).some((h) => h.calib);
    if (pressed && !this.calibrateHeld) this.onCalibrate?.(this.calibration(out));
    this.calibrateHeld = pressed;
    return out;
  }

  /** A hand's orientation from its controller: the controller's heading only (yaw about the
   * vertical), palm down. Grip spaces differ between controllers (a Touch controller's is
   * pitched 45 degrees from its ray) and the task needs only the yaw: a held part stays flat. */
  heading(q) {
    const fwd = new THREE.Vector3(0, 0, -1).applyQuaternion(q); // XR: -z is forward
    if (Math.hypot(fwd.x, fwd.z) < 0.2) fwd.set(0, 1, 0).applyQuaternion(q); // pointing down
    // in the world's axes (the calibration's yaw included); an identity hand's fingers point +y
    fwd.applyQuaternion(this.root.quaternion.clone().invert());
    return yawQuat(Math.atan2(-fwd.x, fwd.y));
  }

  /** The calibration from the present poses: the table height from the right (else left)
   * controller held on the table top, the standing point (XR x, z) from the head. */
  calibration(hands) {
    const h = hands.right || hands.left;
    const head = this.headXr();
    return { tableHeight: h ? h.xr.y : null, origin: head ? [head.x, head.z] : null, yawRad: this.headYaw() };
  }

  /** The head's heading about the vertical (0: XR -z, positive to the left); null when it looks
   * (nearly) straight up or down. */
  headYaw() {
    const q = new THREE.Quaternion();
    this.renderer.xr.getCamera().getWorldQuaternion(q);
    const fwd = new THREE.Vector3(0, 0, -1).applyQuaternion(q);
    if (Math.hypot(fwd.x, fwd.z) < 0.2) return null;
    return Math.atan2(-fwd.x, -fwd.z);
  }

  headXr() {
    const cam = this.renderer.xr.getCamera();
    const p = new THREE.Vector3();
    cam.getWorldPosition(p);
    return p;
  }

  sample(hands) {
    const cam = this.renderer.xr.getCamera();
    const hp = new THREE.Vector3();
    const hq = new THREE.Quaternion();
    cam.getWorldPosition(hp);
    cam.getWorldQuaternion(hq);
    const s = { head: { position: toWorldPosition(this.root, hp), orientation: toWorldQuaternion(this.root, hq) } };
    for (const name of ['left', 'right']) {
      const h = hands[name];
      if (!h) continue;
      s[name] = { position: h.p, orientation: h.q };
      s[`${name}_grip`] = h.grip;
    }
    return s;
  }
}
