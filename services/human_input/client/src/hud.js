// The small status panel: run state, task time, role (driver or spectator), connection; the
// desktop key help; the last message. In a headset the same text is a narrow panel that
// follows the gaze lazily: above the middle of the view (over the board, between the robots),
// PANEL_DIST_M away, so the arms always pass in front of it and it never hides a robot; it stays
// where it is while the gaze moves a little, and glides back once the head turns more than
// PANEL_TURN_DEG or tilts more than PANEL_TILT_DEG (enough to look up at it and read it) from
// where it was put. Its text's em is PANEL_EM_DEG tall.
import * as THREE from 'three';
import { textTexture } from './scene.js';
import { overlaps, pageBoxes } from './screen-rect.js';

const RUN_TEXT = {
  waiting_first_grab: 'ready: the task starts at your first grab',
  running: 'running',
  finished: 'task finished: thank you',
  stopped: 'stopped by the experimenter',
  failed: 'ended by an error',
};
const MESSAGE_GAP_PX = 8; // between the page's message and its status box
export const MESSAGE_MIN_MS = 4000; // a warning stays at least this long: long enough to read
const PANEL_COLUMNS = 30; // the headset's panel wraps its lines here (it stays narrow)
const PANEL_DIST_M = 2.4; // beyond the robots from where the person stands
const PANEL_UP_DEG = 27; // its centre above the gaze it follows
const PANEL_TURN_DEG = 15; // it glides back when the head turns this far from where it was put
const PANEL_TILT_DEG = 30; // ... or tilts this far (more than PANEL_UP_DEG: it can be looked at)
const PANEL_EM_DEG = 1.15; // its text's em, seen from the eye
const PANEL_PX = 32; // the texture's em (px)
const SHOWN_KEEP = 50; // messages kept in `shown` (what the page has said, for the tests)

/** `text`'s lines, each broken at spaces into lines of at most `columns` characters. */
function wrap(text, columns) {
  const out = [];
  for (const line of text.split('\n')) {
    let cur = '';
    for (const word of line.split(' ')) {
      if (cur && cur.length + 1 + word.length > columns) {
        out.push(cur);
        cur = word;
      } else {
        cur = cur ? `${cur} ${word}` : word;
      }
    }
    out.push(cur);
  }
  return out;
}

export class Hud {
  constructor() {
    this.panel = document.getElementById('status');
    this.help = document.getElementById('help');
    this.msg = document.getElementById('message');
    this.values = { connection: 'connecting', role: '-', run: '-', task: '-', hand: '', wait: '' };
    this.heldUntil = 0; // a warning on screen until then
    this.pending = null; // the message that replaces it then
    this.lastText = '';
    this.sprite = null;
    // what was on screen, oldest first: [{text, kind, atMs}] (a slow machine may read the page
    // only after a short message has given way to the next)
    this.shown = [];
  }

  set(key, value) {
    this.values[key] = value;
  }

  /** Shows `text` (kind '' | 'error' | 'alert' | 'warn' | 'over'). An alert (a collision) or
   * a warning stays at least MESSAGE_MIN_MS; what comes meanwhile waits for its turn (the
   * latest wins), except an alert, which is shown at once, and the end. */
  message(text, kind = '', { force = false } = {}) {
    if (!this.msg) return;
    const cls = kind === true ? 'error' : kind || '';
    if (this.msg.className === 'over' && cls !== 'over') return; // the end stays on screen
    const now = performance.now();
    if (!force && cls !== 'alert' && cls !== 'over' && now < this.heldUntil) {
      this.pending = { text, cls };
      return;
    }
    this.pending = null;
    this.heldUntil = cls === 'warn' || cls === 'alert' ? now + MESSAGE_MIN_MS : 0;
    this.msg.textContent = text;
    this.msg.className = cls;
    this.msg.style.display = text ? 'block' : 'none';
    this.placeMessage();
    this.shownText = text;
    if (text) {
      this.shown.push({ text, kind: cls, atMs: now });
      if (this.shown.length > SHOWN_KEEP) this.shown.shift();
    }
  }

  /** A new trial of a session: the last one's end leaves the screen. */
  clearEnd() {
    if (!this.msg) return;
    this.msg.className = '';
    this.heldUntil = 0;
    this.pending = null;
    this.message('');
  }

  showHelp(show) {
    if (this.help) this.help.style.display = show ? 'block' : 'none';
  }

  /** `inWorld`: the headset's panel, whose task time counts whole seconds (its texture is
   * drawn anew when its text changes: once a second, not ten times). */
  lines(inWorld = false) {
    const v = this.values;
    const task = inWorld ? String(v.task).replace(/\.\d s$/, ' s') : v.task;
    const out = [
      `run: ${RUN_TEXT[v.run] || v.run}`,
      `task time: ${task}`,
      `role: ${v.role}`,
      `connection: ${v.connection}`,
    ];
    if (v.wait) out.push(v.wait);
    if (v.hand) out.push(v.hand);
    return out;
  }

  /** Called a few times a second (not every frame: the text rarely changes). */
  refresh(root) {
    if (this.pending && performance.now() >= this.heldUntil) {
      const { text, cls } = this.pending;
      this.message(text, cls);
    }
    const lines = this.lines();
    if (this.panel) this.panel.textContent = lines.join('\n');
    this.placeMessage();
    // the headset has no page overlay: its panel carries the message too
    const panelLines = this.lines(true);
    const all = this.shownText ? [...panelLines, '', this.shownText] : panelLines;
    this.saying = all.join('\n'); // what it says, before its lines are wrapped
    const inWorld = wrap(this.saying, PANEL_COLUMNS);
    const text = inWorld.join('\n');
    if (text === this.lastText) return;
    this.lastText = text;
    if (root) this.updateSprite(root, inWorld);
  }

  /** The page's message (centred at the top) never lies over the status box (top left, as
   * wide as its longest line): it moves right of it where the page is wide enough, else below
   * it. The end's message (centred lower) stays where it is. */
  placeMessage() {
    const m = this.msg;
    if (!m) return;
    m.style.left = '';
    m.style.top = '';
    m.style.transform = '';
    if (m.className === 'over') return;
    const { status: s, message: r } = pageBoxes(['status', 'message']); // those showing
    if (!s || !r || !overlaps(s, r)) return;
    const width = r.x1 - r.x0;
    if (s.x1 + MESSAGE_GAP_PX + width <= window.innerWidth - MESSAGE_GAP_PX) {
      m.style.left = `${s.x1 + MESSAGE_GAP_PX}px`;
      m.style.transform = 'none';
    } else {
      m.style.top = `${s.y1 + MESSAGE_GAP_PX}px`;
    }
  }

  /** Per XR frame: the panel follows the gaze of `eye` (a camera) lazily. */
  follow(eye) {
    const s = this.sprite;
    if (!s || !s.visible) return;
    const p = eye.getWorldPosition(new THREE.Vector3());
    const gaze = eye.getWorldDirection(new THREE.Vector3());
    if (!this.anchor || this.farFrom(gaze)) {
      this.gliding = true;
      this.anchor = this.anchor || gaze.clone();
    }
    const now = performance.now();
    const dt = Math.min(1, (now - (this.lastFollowMs ?? now)) / 1000);
    this.lastFollowMs = now;
    if (this.gliding) {
      // about 0.3 s to catch up, whatever the frame rate: a glide, not a jump
      this.anchor.lerp(gaze, 1 - Math.exp(-dt / 0.1)).normalize();
      if (this.anchor.angleTo(gaze) < 0.01) {
        this.anchor.copy(gaze);
        this.gliding = false;
      }
    }
    // the anchor's direction turned up by PANEL_UP_DEG, about the horizontal axis across it
    const across = new THREE.Vector3().crossVectors(this.anchor, new THREE.Vector3(0, 1, 0));
    if (across.lengthSq() < 1e-6) across.set(1, 0, 0);
    across.normalize();
    const dir = this.anchor.clone().applyAxisAngle(across, THREE.MathUtils.degToRad(PANEL_UP_DEG));
    s.position.copy(p).addScaledVector(dir, PANEL_DIST_M);
    s.lookAt(p); // its face (+z) towards the eye, upright
    this.emM = 2 * PANEL_DIST_M * Math.tan(THREE.MathUtils.degToRad(PANEL_EM_DEG) / 2);
    this.scalePanel();
  }

  /** The gaze has turned or tilted too far from the anchor for the panel to stay. */
  farFrom(gaze) {
    const yaw = (v) => Math.atan2(v.x, -v.z);
    const pitch = (v) => Math.asin(THREE.MathUtils.clamp(v.y, -1, 1));
    let turn = Math.abs(yaw(gaze) - yaw(this.anchor));
    turn = Math.min(turn, 2 * Math.PI - turn);
    const tilt = Math.abs(pitch(gaze) - pitch(this.anchor));
    return turn > THREE.MathUtils.degToRad(PANEL_TURN_DEG) || tilt > THREE.MathUtils.degToRad(PANEL_TILT_DEG);
  }

  scalePanel() {
    const s = this.sprite;
    const h = ((this.emM || 0.04) * s.userData.texHeight) / PANEL_PX;
    s.scale.set(h * s.userData.aspect, h, 1);
  }

  // the in-headset panel: a plane in the scene (not the world: it follows the head)
  updateSprite(root, lines) {
    const { tex, aspect } = textTexture(lines, { px: PANEL_PX, bg: 'rgba(20,20,30,0.85)', fg: '#eee' });
    if (!this.sprite) {
      this.sprite = new THREE.Mesh(
        new THREE.PlaneGeometry(1, 1),
        new THREE.MeshBasicMaterial({ map: tex, transparent: true }),
      );
      this.sprite.name = 'panel';
      this.sprite.visible = false;
      root.parent.add(this.sprite);
    } else {
      this.sprite.material.map.dispose();
      this.sprite.material.map = tex;
    }
    this.sprite.userData.texHeight = tex.image.height;
    this.sprite.userData.aspect = aspect;
    this.sprite.userData.emFraction = PANEL_PX / tex.image.height; // the em's share of its height
    this.scalePanel();
  }

  /** The panel is put anew where the gaze is at the next frame (entering VR, a calibration). */
  replacePanel() {
    this.anchor = null;
  }

  setInWorld(visible) {
    this.replacePanel();
    if (this.sprite) this.sprite.visible = visible;
  }
}
