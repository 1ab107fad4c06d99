// The participant's page: connects to the bridge, builds the scene it sends, renders it in a
// headset (WebXR) or on a desktop, and sends the participant's head, hands and grips back.
// Query parameters: token, driver (the participant's key: this page drives the hands; without
// it the page watches), mode=desktop|xr, table_height (m), stand=x,y (m), rate (Hz),
// session=1 (the page of `hrc session`: its screens between trials, each trial's bridge on the
// port the session names), test=iwer (loads the WebXR emulation, for the browser tests only).
import * as THREE from 'three';
import { Bridge, FRAME_RATE_HZ, HEARTBEAT_MS } from './net.js';
import { World } from './scene.js';
import { Robots } from './robots.js';
import { DesktopInput, KEY_HELP } from './input-desktop.js';
import { XrInput } from './input-xr.js';
import { Hud } from './hud.js';
import { play, soundForEvent, unlockAudio } from './audio.js';
import { DEFAULT_STAND, DEFAULT_TABLE_HEIGHT, placeRoot } from './frames.js';
import { FormView, FORM_H, FORM_W } from './form.js';
import { FormXr } from './form-xr.js';
import { SessionLink } from './session.js';
import {
  ndcRect, overlaps, pageBoxes, planeCorners, spriteCorners, spriteRect,
} from './screen-rect.js';

const params = new URLSearchParams(window.location.search);

function numberParam(name, fallback, lo, hi) {
  const raw = params.get(name);
  if (raw === null) return fallback;
  const v = Number(raw);
  if (!Number.isFinite(v) || v < lo || v > hi) {
    console.warn(`ignoring ${name}=${raw}: expected a number in [${lo}, ${hi}]`);
    return fallback;
  }
  return v;
}

function standParam() {
  const raw = params.get('stand');
  if (!raw) return [...DEFAULT_STAND];
  const xy = raw.split(',').map(Number);
  if (xy.length !== 2 || !xy.every((v) => Number.isFinite(v) && Math.abs(v) < 5)) {
    console.warn(`ignoring stand=${raw}: expected x,y in metres`);
    return [...DEFAULT_STAND];
  }
  return xy;
}

// Frames drawn per second at most outside a headset (0: every frame the browser offers), and
// as many asked of the bridge (instead of FRAME_RATE_HZ). A page beside the trial on one machine
// (the experimenter's spectator view, software WebGL) then leaves the CPU to the trial: its own,
// and the bridge's, which encodes every frame for every page. In a headset every frame is drawn
// and asked for: the headset shows what it gets.
const MAX_FPS = numberParam('fps', 0, 1, 240);
// The 3D view's resolution against the window's, outside a headset (0.1-1): on a machine without a
// GPU a frame's cost goes with its pixels (software WebGL), and the panel and messages, drawn by the
// page over the view, stay sharp.
const RENDER_SCALE = numberParam('scale', 1, 0.1, 1);
const KEEPALIVE_MS = 500; // an unchanged sample is still sent this often
// A "Waiting.." label comes down at most this far (m), in these steps, to keep clear of the
// desktop's status panel or the headset's (from 0.6 m above its robot's base: still above the
// arm's elbow).
const LABEL_DROP_M = 0.3;
const LABEL_STEP_M = 0.03;
const OVER = new Set(['finished', 'stopped', 'failed']); // the trial is over
const END_TEXT = {
  finished: 'The task is finished. Thank you!',
  stopped: 'The experimenter has stopped the trial.',
  failed: 'The trial has ended because of a problem:',
};

/** WebGL drawn by the CPU (SwiftShader, llvmpipe: headless browsers, machines without a GPU),
 * where antialiasing costs about a third of each frame. */
function softwareWebGl() {
  const gl = document.createElement('canvas').getContext('webgl2');
  if (!gl) return false;
  const info = gl.getExtension('WEBGL_debug_renderer_info');
  const name = info ? String(gl.getParameter(info.UNMASKED_RENDERER_WEBGL)) : '';
  gl.getExtension('WEBGL_lose_context')?.loseContext();
  return /swiftshader|llvmpipe|software/i.test(name);
}

async function main() {
  const emulatedXr = params.get('test') === 'iwer';
  if (emulatedXr) {
    // the WebXR emulation runtime, a separate bundle: only the browser tests load it
    const url = new URL('assets/iwer.js', document.baseURI).href;
    await import(/* @vite-ignore */ url);
  }
  const app = new App();
  window.hrcApp = app;
  if (params.has('test')) {
    // the browser tests' hooks (window.hrcTest): a chunk of their own, loaded only for tests
    const hooks = await import('./test-hooks.js');
    hooks.install(app, { maxFps: MAX_FPS, emulatedXr });
  }
  await app.init();
}

class App {
  constructor() {
    this.tableHeight = numberParam('table_height', DEFAULT_TABLE_HEIGHT, 0.3, 1.6);
    this.stand = standParam();
    this.rateHz = numberParam('rate', 90, 1, 240);
    this.role = '-';
    this.run = '-';
    this.runReason = '';
    this.taskT = null;
    this.collision = null; // {robot, part, until}: the last collision, while it is explained
    this.serverHands = null;
    this.lastSample = '';
    this.lastSentMs = 0;
    this.frameMs = []; // intervals between rendered frames
    this.workMs = []; // the page's own work per frame (update + render call)
    this.renderMs = []; // of which the render call
    this.movingN = []; // robots whose joints moved since the frame before
    this.rendered = 0; // frames rendered
    this.drawCalls = 0; // in the last frame
    this.beforeRender = null; // set by the browser tests' hooks (test-hooks.js)
    this.events = [];
    this.frames = 0;
    this.sceneMsg = null;
  }

  async init() {
    const canvas = document.getElementById('view');
    const aa = params.get('aa');
    const antialias = aa === null ? !softwareWebGl() : aa !== '0';
    // the stencil draws each robot's protective zone (ssm) as one volume
    const renderer = new THREE.WebGLRenderer({ canvas, antialias, stencil: true });
    renderer.setPixelRatio(Math.min(window.devicePixelRatio, 2) * RENDER_SCALE);
    renderer.setSize(window.innerWidth, window.innerHeight, false);
    renderer.xr.enabled = true;
    this.renderer = renderer;

    const scene = new THREE.Scene();
    scene.background = new THREE.Color('#b9c4cf');
    scene.add(new THREE.HemisphereLight('#ffffff', '#444444', 1.6));
    const sun = new THREE.DirectionalLight('#ffffff', 1.8);
    sun.position.set(1, 3, 1.5);
    scene.add(sun);
    this.scene = scene;

    this.root = new THREE.Group();
    placeRoot(this.root, this.tableHeight, this.stand);
    scene.add(this.root);
    this.camera = new THREE.PerspectiveCamera(62, window.innerWidth / window.innerHeight, 0.02, 30);
    scene.add(this.camera);

    this.world = new World(this.root);
    this.robotGroup = new THREE.Group();
    this.root.add(this.robotGroup);
    this.robots = new Robots(this.robotGroup, (m) => this.hud.message(m, true));
    this.hud = new Hud();
    this.desktop = new DesktopInput({
      canvas,
      camera: this.camera,
      root: this.root,
      sendNow: () => this.sendSample(performance.now(), this.localHands(), true),
    });
    this.desktop.placeCamera();
    this.xr = new XrInput({ renderer, root: this.root, onCalibrate: (c) => this.calibrate(c) });
    for (const ev of ['sessionstart', 'sessionend']) {
      renderer.xr.addEventListener(ev, () => this.bridge?.setFrameRate(this.frameRateHz()));
    }
    document.getElementById('help').textContent = KEY_HELP.join('\n');

    const xrOk = await XrInput.supported();
    this.mode = params.get('mode') || (xrOk ? 'xr' : 'desktop');
    this.setupModeUi(xrOk);

    window.addEventListener('resize', () => this.resize());
    window.addEventListener('keydown', (e) => {
      if (e.key === 'F1') {
        e.preventDefault();
        this.helpShown = !this.helpShown;
        this.hud.showHelp(this.helpShown);
      }
    });
    for (const ev of ['pointerdown', 'keydown']) window.addEventListener(ev, unlockAudio);

    this.bridge = null;
    if (params.get('session')) this.startSession();
    else this.connectBridge('');
    setInterval(() => this.refresh(), 250);
    setInterval(() => this.bridge?.heartbeat(), HEARTBEAT_MS);
    renderer.setAnimationLoop((t, frame) => this.onFrame(t, frame));
  }

  /** Frames a second to ask of the bridge: as many as the page draws (`fps`), in a headset all. */
  frameRateHz() {
    return MAX_FPS && !this.renderer.xr.isPresenting ? MAX_FPS : FRAME_RATE_HZ;
  }

  /** The link to a trial's bridge: the page's own server (`host` ''), or a session's trial. */
  connectBridge(host) {
    this.bridge = new Bridge({
      token: params.get('token'),
      driver: params.get('driver'),
      host,
      frameRateHz: this.frameRateHz(),
      onMessage: (m) => this.onMessage(m),
      onStatus: (s, detail) => {
        this.hud.set('connection', detail ? `${s} (${detail})` : s);
        if (s === 'lost' && !this.linkLost) {
          this.linkLost = true;
          this.hud.message('Connection to the trial lost: reconnecting...', 'error', { force: true });
        } else if (s === 'connected' && this.linkLost) {
          this.linkLost = false;
          this.hud.message('', '', { force: true });
        }
      },
    });
  }

  // ------------------------------------------------------------------ a session's screens
  startSession() {
    this.form = new FormView({ onSend: (msg) => this.session.send(msg) });
    const c = this.form.canvas;
    c.id = 'form';
    document.body.appendChild(c);
    this.formXr = new FormXr({ renderer: this.renderer, scene: this.scene, form: this.form });
    c.addEventListener('click', (e) => {
      const r = c.getBoundingClientRect();
      this.form.click(((e.clientX - r.left) * FORM_W) / r.width, ((e.clientY - r.top) * FORM_H) / r.height);
    });
    window.addEventListener('keydown', (e) => {
      if (this.form.visible() && this.form.key(e)) e.preventDefault();
    });
    this.hud.set('connection', 'session: connecting');
    this.sessionNotice = ''; // why the session's link is down, in words ('' while it is up)
    this.session = new SessionLink({
      token: params.get('token'),
      driver: params.get('driver'),
      onScreen: (m) => this.onScreen(m),
      onStatus: (s) => {
        if (!this.bridge || OVER.has(this.run)) this.hud.set('connection', `session: ${s}`);
        if (s === 'replaced') this.hud.message('This page was replaced by another page of the participant.', 'over');
        // in words, on the form the participant reads (desktop and headset alike)
        const notice = {
          away: 'The session is not running: this page goes on when it is started again.',
          refused: 'This link no longer opens the session: ask the experimenter for the new one.',
        };
        this.form.setNotice(s === 'connected' ? '' : notice[s] || this.form.notice || '');
        // in a trial the form is not on screen: the participant reads it in the message (a
        // session killed mid-trial takes its trial along: "the next screen follows" would lie)
        const was = this.sessionNotice;
        if (s === 'connected' || notice[s]) this.sessionNotice = notice[s] || '';
        if (this.sessionNotice === was || this.form.visible() || !this.trialPort) return;
        if (OVER.has(this.run)) this.showEnd();
        else if (this.sessionNotice) this.hud.message(this.sessionNotice, 'error', { force: true });
      },
    });
  }

  onScreen(m) {
    if (m.kind === 'trial') {
      if (this.trialPort !== m.port) this.startTrial(m.port);
    } else if (this.trialPort) {
      // between trials: the last trial's world stays in view, but it is over (a trial the
      // session stopped included); the next one is a new world
      this.bridge?.rest();
      this.trialPort = null;
      this.sceneMsg = null;
      this.frames = 0;
    }
    this.form.show(m);
    this.showForm();
  }

  /** The form over the page (desktop), or on its panel (headset: FormXr, per frame). */
  showForm() {
    const desktop = this.form.visible() && !this.xr.active();
    this.form.canvas.style.display = desktop ? 'block' : 'none';
    // the form is all there is to read between trials (it shows the progress): the status
    // panel and the key help, whose corners it covered, wait for the next trial (index.html)
    document.body.classList.toggle('form-up', desktop);
    if (this.form.visible()) this.hud.clearEnd();
  }

  /** A trial of the session begins: its bridge is on `port` of this page's host. */
  startTrial(port) {
    this.bridge?.rest();
    this.trialPort = port;
    const host = `${window.location.hostname}:${port}`;
    this.robots.baseUrl = `${window.location.protocol}//${host}/`;
    this.run = '-';
    this.runReason = '';
    this.taskT = null;
    this.collision = null;
    this.waitFor = null;
    this.serverHands = null;
    this.events = [];
    this.frames = 0;
    this.sceneMsg = null;
    this.hud.clearEnd();
    this.hud.set('run', '-');
    if (this.mode === 'desktop') {
      this.desktop.enable();
      this.hud.showHelp(this.helpShown);
    }
    this.connectBridge(host);
  }

  setupModeUi(xrOk) {
    const enter = document.getElementById('enter-vr');
    if (this.mode === 'xr') {
      enter.style.display = 'block';
      enter.disabled = !xrOk;
      enter.textContent = xrOk ? 'Enter VR' : 'WebXR (immersive-vr) is not available';
      enter.addEventListener('click', async () => {
        unlockAudio();
        try {
          await this.xr.start(this.scene);
          enter.style.display = 'none';
          this.hud.setInWorld(true);
        } catch (err) {
          this.hud.message(`cannot start VR: ${err}`, true);
        }
      });
      this.hud.showHelp(false);
      this.hud.set('hand', 'calibrate: right controller on the table top, press A');
    } else {
      this.desktop.enable();
      this.helpShown = true;
      this.hud.showHelp(true);
    }
  }

  calibrate({ tableHeight, origin, yawRad }) {
    if (tableHeight !== null && tableHeight > 0.3 && tableHeight < 1.6) this.tableHeight = tableHeight;
    const yaw = yawRad ?? this.root.userData.yawRad;
    placeRoot(this.root, this.tableHeight, this.stand, origin || this.root.userData.origin, yaw);
    if (this.sceneMsg) this.world.buildFurniture(); // the floor moves with the table height
    const deg = Math.round(THREE.MathUtils.radToDeg(yaw));
    this.hud.replacePanel();
    // the panel is what a headset shows (no message: it would say it twice)
    this.hud.set('hand', `calibrated: table ${this.tableHeight.toFixed(2)} m high, facing ${deg}\u00b0 (A: redo)`);
  }

  resize() {
    if (this.renderer.xr.isPresenting) return;
    this.camera.aspect = window.innerWidth / window.innerHeight;
    this.camera.updateProjectionMatrix();
    this.renderer.setSize(window.innerWidth, window.innerHeight, false);
  }

  // ------------------------------------------------------------------ messages from the bridge
  onMessage(m) {
    switch (m.type) {
      case 'hello':
        if (m.role) {
          // A page that becomes the driver starts from open hands, as the bridge has them (a
          // driver's hands open when its page is gone); the same page back after a redial
          // (`resumed`) keeps its hands and what they hold.
          if (m.role === 'driver' && !m.resumed && this.desktop.releaseGrips() && this.role === 'driver') {
            this.hud.message('Connection back: your hand let go of the part. Take it again.', 'warn');
          }
          this.role = m.role;
        }
        this.hud.set('role', this.role === 'spectator' ? 'spectator (watching)' : this.role);
        if (m.auth_required) this.hud.message('the bridge needs a token: open the URL with ?token=...', true);
        break;
      case 'scene':
        this.sceneMsg = m;
        this.world.build(m);
        this.robots.build(m.robots, m.ssm_zone);
        this.hud.message('');
        break;
      case 'frame':
        if (this.frozen) break; // a test holds the picture still (hrcTest.freeze)
        this.frames++;
        this.world.applyFrame(m);
        this.robots.applyFrame(m);
        if (m.run && m.run !== this.run) this.setRun(m.run, '');
        if (m.task_t_s !== undefined) this.taskT = m.task_t_s;
        if (m.hands) this.serverHands = m.hands;
        if (this.freezeOn && this.awaitedOnScreen(this.freezeOn)) {
          this.frozen = true; // hrcTest.freezeWhen: the awaited moment is on screen now
          this.freezeOn = null;
        }
        break;
      case 'event':
        this.onEvent(m);
        break;
      case 'run':
        this.setRun(m.state, m.reason);
        break;
      case 'error':
        if (!String(m.error).startsWith('spectator')) this.hud.message(`bridge: ${m.error}`, true);
        break;
      default:
        break;
    }
  }

  setRun(state, reason) {
    if (OVER.has(this.run) && !OVER.has(state)) return; // the end stays the end
    if (state === this.run && !reason) return;
    this.run = state;
    if (reason) this.runReason = reason;
    this.hud.set('run', state);
    if (OVER.has(state)) this.showEnd();
  }

  /** The trial is over: say how, once, and rest (no sending, no reconnecting, no errors). */
  showEnd() {
    // (a session that went away mid-trial took its trial along: nobody stopped it)
    const head = (this.sessionNotice ? 'The trial has stopped.' : END_TEXT[this.run]) || 'The trial is over.';
    if (this.sessionNotice) this.hud.set('run', 'stopped (the session is not running)');
    // one line of the reason: the log line without its time, the watchdog's first clause
    const why = this.run === 'failed'
      ? `\n${String(this.runReason || 'unknown').replace(/^\s*[\d.]+\s*sec\s*:\s*/, '').split(/[;\n]/)[0].slice(0, 160)}`
      : '';
    this.waitFor = null;
    this.hud.set('wait', '');
    this.collision = null;
    const next = this.sessionNotice
      || (this.session ? 'The next screen follows in a moment.' : 'Please wait for the experimenter.');
    this.hud.message(`${head}${why}\n${next}`, 'over');
    this.hud.showHelp(false);
    this.desktop.disable(); // the hands stay where they are: nothing to do any more
    this.bridge?.rest();
  }

  onEvent(ev) {
    this.events.push(ev);
    if (this.events.length > 500) this.events.shift();
    const sound = soundForEvent(ev.kind);
    if (sound) play(sound, ev.kind + (ev.part ? `:${ev.part}` : ''));
    if (ev.kind !== 'participant_wait') {
      this.waitFor = null;
      this.hud.set('wait', '');
    }
    if (ev.kind === 'collision') {
      const part = this.partHeldBy(ev.robot);
      this.collision = { robot: ev.robot, part, open: true };
      const goal = part ? ` It brings ${part} to its target (marked).` : '';
      this.hud.message(
        `Collision with ${ev.robot}: pull your hand back.\n${ev.robot} backs off, then goes on.${goal}`,
        'alert',
      );
    } else if (ev.kind === 'collision_end' && this.collision) {
      this.collision.open = false;
    } else if (ev.kind === 'continued') {
      const c = this.collision;
      const where = c && c.part ? ` to ${c.part}'s target (marked): keep your hands clear of it` : '';
      this.hud.message(`${c ? c.robot : 'The robots'} goes on${where}.`, 'warn');
      if (c) c.until = performance.now() + 6000;
    } else if (ev.kind === 'participant_wait') {
      this.waitSince = performance.now() - 1000 * (ev.quiet_s ?? 10);
      this.waitFor = ev.part || 'the continue button';
    } else if (ev.kind === 'task_finished') {
      this.hud.message('task finished');
    }
  }

  /** The part a robot holds now ('' if none). */
  partHeldBy(robot) {
    for (const [id, p] of this.world.parts) if (p.holder === robot) return id;
    return '';
  }

  /** hrcTest.freezeWhen's moment: `part` held by `holder` and, if named, `cue` lit. */
  awaitedOnScreen({ part, holder, cue }) {
    return this.world.parts.get(part)?.holder === holder && (!cue || !!this.world.cues.get(cue)?.on);
  }

  /** A few times a second: the panel, the waiting labels, the robot's target after a collision
   * (held still, like the frames, while a test freezes the picture). */
  refresh() {
    if (this.frozen) {
      if (this.frozen === 'scene') this.hud.refresh(this.root);
      return;
    }
    if (this.waitFor && !OVER.has(this.run)) {
      const s = Math.round((performance.now() - this.waitSince) / 1000);
      const who = this.role === 'driver' ? 'you' : 'the participant';
      this.hud.set('wait', `waiting for ${who}: ${this.waitFor}, ${s} s`);
    }
    const c = this.collision;
    if (c && !c.open && c.until && performance.now() > c.until) this.collision = null;
    this.world.showGoal(this.collision ? this.collision.part : '', this.collision?.robot);
    this.world.updateWaitingTexts((rid) => this.waitingText(rid));
    this.keepLabelsClear();
    this.hud.refresh(this.root);
  }

  /** A "Waiting.." label that something drawn over the scene would cover comes down over its
   * robot, a few centimetres at a time, until it is clear: the labels stand high above the
   * robots, where the desktop's boxes (the status panel, a message) are, and where the
   * headset's panel hangs when the person looks up (it is farther than the labels, but the
   * labels are drawn over everything: "run: running" read "n: running" under one). In a headset
   * the label must be clear of the panel in both eyes' views. */
  keepLabelsClear() {
    const inXr = this.xr.active();
    let covered;
    if (inXr) {
      const panel = this.hud.sprite;
      const eyes = this.renderer.xr.getCamera().cameras;
      const panels = panel?.visible ? eyes.map((eye) => ndcRect(eye, planeCorners(panel))) : [];
      covered = (obj) =>
        panels.some((p, i) => overlaps(ndcRect(eyes[i], spriteCorners(eyes[i], obj)), p));
    } else {
      const boxes = Object.values(pageBoxes(['status', 'message']));
      const canvas = this.renderer.domElement;
      covered = (obj) => boxes.some((b) => overlaps(spriteRect(this.camera, canvas, obj), b));
    }
    for (const cue of this.world.cues.values()) {
      if (cue.spec.kind !== 'waiting' || !cue.on) continue;
      const [x, y, z] = cue.obj.userData.anchor;
      for (let dz = 0; dz <= LABEL_DROP_M + 1e-9; dz += LABEL_STEP_M) {
        cue.obj.position.set(x, y, z - dz);
        if (!covered(cue.obj)) break;
      }
    }
  }

  /** "Waiting for you: H3" for a robot that waits on a part the participant places. */
  waitingText(rid) {
    if (this.testWaiting?.[rid]) return this.testWaiting[rid]; // (hrcTest.showWaiting)
    const spec = this.world.parts.get(this.partHeldBy(rid))?.spec;
    if (!spec) return '';
    const missing = (spec.after || []).filter((d) => !this.world.parts.get(d)?.placed);
    if (!missing.length) return '';
    const owner = (id) => this.world.parts.get(id)?.spec.owner;
    const mine = missing.filter((d) => owner(d) === 'human');
    const you = this.role === 'driver' ? 'you' : 'the participant';
    if (mine.length) return `Waiting for ${you}: ${mine.join(', ')}`;
    return `Waiting for ${owner(missing[0])}: ${missing.join(', ')}`;
  }

  // ------------------------------------------------------------------ the frame loop
  localHands() {
    if (this.xr.active()) {
      const hands = this.xr.hands();
      // an untracked controller keeps its hand where it was last seen
      this.lastXrHands = { ...(this.lastXrHands || this.desktop.poses()), ...hands };
      return this.lastXrHands;
    }
    return this.desktop.poses();
  }

  onFrame(t, frame) {
    const now = performance.now();
    // (2 ms early: the browser's frames come a little before or after their period)
    if (MAX_FPS && this.lastFrameAt !== undefined && !this.renderer.xr.isPresenting
        && now - this.lastFrameAt < 1000 / MAX_FPS - 2) return;
    if (this.lastFrameAt !== undefined) {
      this.frameMs.push(now - this.lastFrameAt);
      if (this.frameMs.length > 2000) this.frameMs.shift();
    }
    this.lastFrameAt = now;
    const driving = this.role === 'driver';
    // a spectator's controllers draw nothing and send nothing, but calibrate its view (A/X)
    const own = driving || this.xr.active() ? this.localHands() : null;
    const hands = driving ? own : this.spectatorHands();
    if (hands) {
      for (const name of ['left', 'right']) {
        if (hands[name]) this.world.setHand(name, hands[name].p, hands[name].q, hands[name].grip);
      }
      this.world.followHands(driving ? hands : {});
    }
    if (driving && this.sceneMsg && !OVER.has(this.run)) this.sendSample(now, hands);
    if (this.form) {
      this.form.keyboardWanted = this.xr.active(); // text is typed on the panel in a headset
      this.formXr.update(this.xr.active() && this.form.visible());
      const overlay = this.form.visible() && !this.xr.active();
      if ((this.form.canvas.style.display === 'block') !== overlay) this.showForm();
    }
    this.world.animate(now);
    this.hud.set('task', this.taskT === null || this.taskT === undefined ? '-' : `${this.taskT.toFixed(1)} s`);
    if (!this.xr.active() && this.mode === 'desktop') this.hud.set('hand', driving ? this.desktop.statusLine() : '');
    if (this.xr.active()) {
      // between a session's trials the form is all there is to read (it shows the progress):
      // the status panel, which would hang over the form's title, waits for the next trial
      const formUp = !!this.form?.visible();
      if (formUp !== this.panelAsideForForm) {
        this.panelAsideForForm = formUp;
        this.hud.setInWorld(!formUp);
      }
      this.hud.follow(this.renderer.xr.getCamera());
    }
    this.beforeRender?.(); // the browser tests' hooks (test-hooks.js): what a test hides
    const updated = performance.now();
    this.renderer.render(this.scene, this.camera);
    const done = performance.now();
    this.workMs.push(done - now);
    this.renderMs.push(done - updated);
    this.drawCalls = this.renderer.info.render.calls; // this frame's, all views
    this.rendered++;
    this.movingN.push(this.robots.movedSinceLastAsked()); // the bench counts frames of 2
    if (this.workMs.length > 2000) this.workMs.shift();
    if (this.renderMs.length > 2000) this.renderMs.shift();
    if (this.movingN.length > 2000) this.movingN.shift();
  }

  spectatorHands() {
    const s = this.serverHands;
    if (!s) return null;
    const out = {};
    for (const name of ['left', 'right']) {
      if (s[name]) out[name] = { p: s[name].p, q: s[name].q, grip: s[name].grip ?? 0 };
    }
    return out;
  }

  sendSample(now, hands, force = false) {
    if (this.role !== 'driver' || !this.sceneMsg || OVER.has(this.run)) return;
    if (!force && now - this.lastSentMs < 1000 / this.rateHz - 0.5) return;
    const sample = this.xr.active() ? this.xr.sample(hands) : this.desktop.sample();
    for (const name of ['left', 'right']) {
      if (!sample[name]) sample[name] = { position: hands[name].p, orientation: hands[name].q };
      if (sample[`${name}_grip`] === undefined) sample[`${name}_grip`] = hands[name].grip;
    }
    const text = JSON.stringify(sample);
    if (!force && text === this.lastSample && now - this.lastSentMs < KEEPALIVE_MS) return;
    if (this.bridge?.send(sample)) {
      this.lastSample = text;
      this.lastSentMs = now;
    }
  }
}

main().catch((err) => {
  console.error(err);
  const m = document.getElementById('message');
  if (m) {
    m.textContent = `the page failed to start: ${err}`;
    m.style.display = 'block';
  }
});
