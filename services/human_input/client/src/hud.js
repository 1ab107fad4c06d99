// The small status panel: run state, task time, role (driver or spectator), connection; the
// desktop key help; the last message. In a headset the same text floats beyond the board.
import * as THREE from 'three';
import { textTexture } from './scene.js';

const RUN_TEXT = {
  waiting_first_grab: 'ready: the task starts at your first grab',
  running: 'running',
  finished: 'finished: thank you',
  failed: 'failed',
};

export class Hud {
  constructor() {
    this.panel = document.getElementById('status');
    this.help = document.getElementById('help');
    this.msg = document.getElementById('message');
    this.values = { connection: 'connecting', role: '-', run: '-', task: '-', hand: '' };
    this.lastText = '';
    this.sprite = null;
  }

  set(key, value) {
    this.values[key] = value;
  }

  message(text, isError = false) {
    if (!this.msg) return;
    this.msg.textContent = text;
    this.msg.className = isError ? 'error' : '';
    this.msg.style.display = text ? 'block' : 'none';
  }

  showHelp(show) {
    if (this.help) this.help.style.display = show ? 'block' : 'none';
  }

  lines() {
    const v = this.values;
    const out = [
      `run: ${RUN_TEXT[v.run] || v.run}`,
      `task time: ${v.task}`,
      `role: ${v.role}   connection: ${v.connection}`,
    ];
    if (v.hand) out.push(v.hand);
    return out;
  }

  /** Called a few times a second (not every frame: the text rarely changes). */
  refresh(root) {
    const lines = this.lines();
    const text = lines.join('\n');
    if (text === this.lastText) return;
    this.lastText = text;
    if (this.panel) this.panel.textContent = text;
    if (root) this.updateSprite(root, lines);
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
