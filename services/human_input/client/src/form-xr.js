// The session's screens in the headset: the form's canvas on a panel put in front of the
// participant when a screen appears (FORM_DIST_M ahead, a little below the eyes, facing them),
// and a ray from each controller. Where a ray meets the panel a dot follows it; pulling that
// controller's trigger clicks there.
import * as THREE from 'three';
import { FORM_H, FORM_W } from './form.js';

const FORM_DIST_M = 0.9;
const FORM_WIDTH_M = 0.9;
const FORM_DROP_M = 0.12; // its centre below the eyes
const RAY_M = 3;
const TRIGGER_ON = 0.6; // a pull past this clicks, once, until it is let go below TRIGGER_OFF
const TRIGGER_OFF = 0.3;

export class FormXr {
  constructor({ renderer, scene, form }) {
    this.renderer = renderer;
    this.form = form;
    this.texture = new THREE.CanvasTexture(form.canvas);
    this.texture.colorSpace = THREE.SRGBColorSpace;
    this.panel = new THREE.Mesh(
      new THREE.PlaneGeometry(FORM_WIDTH_M, (FORM_WIDTH_M * FORM_H) / FORM_W),
      new THREE.MeshBasicMaterial({ map: this.texture, depthTest: false }),
    );
    this.panel.name = 'form';
    this.panel.renderOrder = 10; // over the scene: nothing of the world may hide a question
    this.panel.visible = false;
    scene.add(this.panel);
    this.rays = [0, 1].map((i) => {
      const c = renderer.xr.getController(i);
      const line = new THREE.Line(
        new THREE.BufferGeometry().setFromPoints([new THREE.Vector3(), new THREE.Vector3(0, 0, -RAY_M)]),
        new THREE.LineBasicMaterial({ color: '#ffdd33' }),
      );
      line.name = 'ray';
      line.visible = false;
      c.add(line);
      scene.add(c);
      const ray = { controller: c, line, source: null, pulled: false };
      c.addEventListener('connected', (e) => { ray.source = e.data; });
      c.addEventListener('disconnected', () => { ray.source = null; });
      return ray;
    });
    this.version = -1;
    this.placed = false;
    this.raycaster = new THREE.Raycaster();
  }

  /** Per XR frame: the panel shown (and put in front of the head when a new screen came), the
   * rays, the pointer, a trigger pull. */
  update(show) {
    const wasShown = this.panel.visible;
    this.panel.visible = show;
    for (const r of this.rays) r.line.visible = show && !!r.source;
    if (!show) {
      this.placed = false;
      return;
    }
    if (!wasShown || !this.placed || this.screenId !== this.form.screen?.id) this.place();
    let hit = null;
    for (const r of this.rays) {
      if (!r.source) continue;
      const uv = this.aim(r);
      const value = this.trigger(r);
      if (uv && (!hit || r.source.handedness === 'right')) hit = { r, uv };
      if (value > TRIGGER_ON && !r.pulled) {
        r.pulled = true;
        if (uv) this.form.click(uv[0], uv[1]);
      } else if (value < TRIGGER_OFF) r.pulled = false;
    }
    this.form.pointer(hit ? hit.uv : null);
    if (this.version !== this.form.version) {
      this.version = this.form.version;
      this.texture.needsUpdate = true;
    }
  }

  /** In front of the head, facing it, upright. */
  place() {
    const cam = this.renderer.xr.getCamera();
    const p = cam.getWorldPosition(new THREE.Vector3());
    const fwd = cam.getWorldDirection(new THREE.Vector3());
    fwd.y = 0;
    if (fwd.lengthSq() < 1e-6) fwd.set(0, 0, -1);
    fwd.normalize();
    this.panel.position.copy(p).addScaledVector(fwd, FORM_DIST_M);
    this.panel.position.y -= FORM_DROP_M;
    this.panel.lookAt(p.x, this.panel.position.y, p.z);
    this.panel.updateMatrixWorld();
    this.placed = true;
    this.screenId = this.form.screen?.id;
  }

  /** Where the controller's ray meets the panel, in canvas px; null if it misses. */
  aim(r) {
    const c = r.controller;
    c.updateMatrixWorld();
    const origin = new THREE.Vector3().setFromMatrixPosition(c.matrixWorld);
    const dir = new THREE.Vector3(0, 0, -1).transformDirection(c.matrixWorld);
    this.raycaster.set(origin, dir);
    this.raycaster.far = RAY_M;
    const hits = this.raycaster.intersectObject(this.panel, false);
    if (!hits.length || !hits[0].uv) return null;
    const { uv } = hits[0];
    return [uv.x * FORM_W, (1 - uv.y) * FORM_H];
  }

  trigger(r) {
    const b = r.source?.gamepad?.buttons?.[0];
    return b ? b.value || (b.pressed ? 1 : 0) : 0;
  }

  /** A canvas point of the form as XR (local-floor) coordinates (for the browser tests). */
  worldPoint(x, y) {
    const local = new THREE.Vector3(
      (x / FORM_W - 0.5) * FORM_WIDTH_M,
      (0.5 - y / FORM_H) * ((FORM_WIDTH_M * FORM_H) / FORM_W),
      0,
    );
    this.panel.updateMatrixWorld();
    return this.panel.localToWorld(local).toArray();
  }
}
