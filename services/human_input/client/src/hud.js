// The small status panel: run state, task time, role (driver or spectator), connection; the
// desktop key help; the last message. In a headset the same text floats beyond the board.
import * as THREE from 'three';
import { textTexture } from './scene.js';

const RUN_TEXT = {
  waiting_first_grab: 'ready: the task starts at your first grab',
  running: 'running',
  finished: 'task finished: thank you',
  stopped: 'stopped by the experimenter',
  failed: 'ended by an error',
};
const MESSAGE_MIN_MS = 4000; // a warning stays at least this long: long enough to read
const PANEL_COLUMNS = 44; // the headset's panel wraps the message here (the panel stays narrow)

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
    this.shownText = text;
  }

  showHelp(show) {
    if (this.help) this.help.style.display = show ? 'block' : 'none';
  }

  lines() {
    const v = this.values;
    const out = [
      `run: ${RUN_TEXT[v.run] || v.run}`,
      `task time: ${v.task}`,
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
    // the headset has no page overlay: its panel carries the message too
    const inWorld = this.shownText ? [...lines, '', ...wrap(this.shownText, PANEL_COLUMNS)] : lines;
    const text = inWorld.join('\n');
    if (text === this.lastText) return;
    this.lastText = text;
    if (this.panel) this.panel.textContent = lines.join('\n');
    if (root) this.updateSprite(root, inWorld);
  }

  // the in-headset panel: a plane beyond the board, facing the participant
  updateSprite(root, lines) {
    const { tex, aspect } = textTexture(lines, { px: 32, bg: 'rgba(20,20,30,0.85)', fg: '#eee' });
    if (!this.sprite) {
      this.sprite = new THREE.Mesh(
        new THREE.PlaneGeometry(1, 1),
        new THREE.MeshBasicMaterial({ map: tex, transparent: true }),
      );
      this.sprite.rotation.set(Math.PI / 2, 0, 0.6, 'ZXY'); // upright, turned to the participant
      this.sprite.position.set(-0.75, 0.35, 0.3); // left of the board, clear of the robots
      this.sprite.visible = false;
      root.add(this.sprite);
    } else {
      this.sprite.material.map.dispose();
      this.sprite.material.map = tex;
    }
    const h = 0.04 * lines.length;
    this.sprite.scale.set(h * aspect, h, 1);
  }

  setInWorld(visible) {
    if (this.sprite) this.sprite.visible = visible;
  }
}
