// The browser tests' hooks on the participant's page (window.hrcTest): what the page shows and
// where, hiding a thing to see whether it is seen, holding the picture still. Loaded only with
// ?test=... in the page's URL (main.js imports this chunk then): a participant's page has none.
import * as THREE from 'three';
import { FORM_H, FORM_W } from './form.js';
import { MESSAGE_MIN_MS } from './hud.js';
import { HEARTBEAT_MS, LOST_MS, SILENT_BEATS } from './net.js';
import { pageBoxes, spriteCorners } from './screen-rect.js';

/** The things a test can hide (and probe) by name: board, furniture, markings, parts, labels,
 * robot:<id>, hands, cue:<id>, panel (the headset's panel and the page's status box). */
function testObjects(app, name) {
  const w = app.world;
  const [kind, id] = name.split(/:(.*)/s);
  switch (kind) {
    case 'board':
    case 'furniture':
      return w.furniture ? [w.furniture.getObjectByName(kind)].filter(Boolean) : [];
    case 'markings':
      return w.markings ? [w.markings] : [];
    case 'parts':
      return [w.partsView.boxes, w.partsView.edges].filter(Boolean);
    case 'labels':
      return [...w.parts.values()].map((p) => p.label);
    case 'robot': {
      const r = app.robots.robots.get(id);
      return r ? [r.holder] : [];
    }
    case 'hands':
      return Object.values(w.hands).flatMap((h) => [h.obj, h.plumb, h.ring]);
    case 'cue': {
      const c = w.cues.get(id);
      return c ? [c.obj] : [];
    }
    case 'panel':
      return [app.hud.sprite, document.getElementById('status')].filter(Boolean);
    default:
      throw new Error(`hrcTest: nothing called '${name}'`);
  }
}

/** A point of `obj` in the root's (world) frame. */
function rootLocal(app, obj, local = new THREE.Vector3()) {
  const v = obj.localToWorld(local.clone());
  return app.root.worldToLocal(v).toArray();
}

/** Where each thing a person should see is, as world points to look at: {name: [[x, y, z]..]}
 * (a robot's links: the centres of the shapes of its base, its middle link and its wrist, the
 * link before the last, whose tool a held part and its label may cover; an outline cue: its
 * corners, as the part it surrounds covers its middle). */
function probePoints(app) {
  const w = app.world;
  const out = {};
  const board = app.sceneMsg?.board;
  if (board) {
    const [cx, cy, cz] = board.center;
    const [sx, sy, sz] = board.size;
    out.board = [];
    for (const fx of [-0.35, 0, 0.35]) for (const fy of [-0.3, 0.3]) out.board.push([cx + fx * sx, cy + fy * sy, cz + sz / 2]);
  }
  for (const [rid, r] of app.robots.robots) {
    if (!r.model) continue;
    const shapes = [];
    r.model.traverse((o) => {
      if (o.isMesh && o.name.startsWith('link:')) shapes.push(o);
    });
    // from the base out: by how many links lie between a shape and the model
    const depth = (o) => {
      let n = 0;
      for (let up = o.parent; up; up = up.parent) n += up.isURDFLink ? 1 : 0;
      return n;
    };
    shapes.sort((a, b) => depth(a) - depth(b));
    const pick = [shapes[0], shapes[Math.floor(shapes.length / 2)], shapes[Math.max(0, shapes.length - 2)]];
    out[`robot:${rid}`] = pick.filter(Boolean).map((m) => {
      m.geometry.computeBoundingBox();
      return rootLocal(app, m, m.geometry.boundingBox.getCenter(new THREE.Vector3()));
    });
  }
  out.parts = [...w.parts.values()]
    .filter((p) => p.mesh.visible)
    .map((p) => [p.mesh.position.x, p.mesh.position.y, p.mesh.position.z + p.spec.size[2] / 2]);
  out.hands = Object.values(w.hands).filter((h) => h.obj.visible).map((h) => h.obj.position.toArray());
  for (const [id, c] of w.cues) {
    if (!c.on || c.spec.kind === 'button') continue;
    const size = c.obj.userData.outlineSize;
    out[`cue:${id}`] = size
      ? [[-1, -1], [1, -1], [1, 1], [-1, 1]].map(([a, b]) => rootLocal(app, c.obj, new THREE.Vector3((a * size[0]) / 2, (b * size[1]) / 2, 0)))
      : [rootLocal(app, c.obj)];
  }
  // the panel's middle and four points around it (an arm may pass in front of some)
  const panel = app.hud.sprite;
  if (panel?.visible) {
    out.panel = [[0, 0], [-0.25, -0.25], [0.25, -0.25], [0.25, 0.25], [-0.25, 0.25]].map(([x, y]) =>
      rootLocal(app, panel, new THREE.Vector3(x, y, 0)),
    );
  }
  return out;
}

/** The eye a picture is taken from: the XR view's first camera, or the desktop camera. */
function eyeCamera(app) {
  return app.renderer.xr.isPresenting ? app.renderer.xr.getCamera().cameras[0] : app.camera;
}

/** Each text on screen (part labels, target names, "Waiting.." labels, the headset's panel):
 * its em's angular height (degrees) from the eye, and its distance (m). */
function textSizes(app) {
  const eye = new THREE.Vector3();
  eyeCamera(app).getWorldPosition(eye);
  const out = [];
  app.scene.traverseVisible((o) => {
    const em = o.userData.emFraction;
    if (!em || !o.layers.test(eyeCamera(app).layers)) return;
    const c = o.getWorldPosition(new THREE.Vector3());
    const s = o.getWorldScale(new THREE.Vector3());
    const d = c.distanceTo(eye);
    const emM = s.y * em;
    out.push({ what: o.name || 'text', em_deg: THREE.MathUtils.radToDeg(2 * Math.atan(emM / 2 / d)), distance_m: d });
  });
  return out;
}
function projectWith(app, xyz) {
  return pagePoint(app, app.root.localToWorld(new THREE.Vector3(...xyz)));
}

/** A world point on the page (CSS pixels), as the eye of the pictures sees it. */
function pagePoint(app, world) {
  const v = world.clone();
  const canvas = app.renderer.domElement;
  const rect = canvas.getBoundingClientRect();
  if (app.renderer.xr.isPresenting) {
    // the first (left) eye's view, in its viewport of the canvas
    const cams = app.renderer.xr.getCamera().cameras;
    const cam = cams[0];
    const vp = cam.viewport; // drawing-buffer pixels
    const scale = rect.width / canvas.width;
    v.project(cam);
    return {
      x: rect.left + (vp.x + ((v.x + 1) / 2) * vp.z) * scale,
      y: rect.top + (canvas.height - vp.y - vp.w + ((1 - v.y) / 2) * vp.w) * scale,
      visible: Math.abs(v.z) <= 1,
    };
  }
  v.project(app.camera);
  return {
    x: rect.left + ((v.x + 1) / 2) * rect.width,
    y: rect.top + ((1 - v.y) / 2) * rect.height,
    visible: Math.abs(v.z) <= 1,
  };
}

/** What a test hides (hrcTest.hide) is kept off every view: moved to a layer no camera
 * renders (objects rebuilt since, as the board after a calibration, are caught here too). */
function applyHidden(app, hidden) {
  for (const [name, reasons] of hidden) {
    const off = reasons.size > 0;
    for (const obj of testObjects(app, name)) {
      if (obj instanceof HTMLElement) obj.style.visibility = off ? 'hidden' : '';
      else obj.traverse((o) => o.layers.set(off ? 31 : 0));
    }
    if (!off) hidden.delete(name);
  }
}

/** An emulated headset (IWER) draws every device frame, in software WebGL as fast as a core
 * lets it, beside the trial; and it clears the picture at each of its frames, so the page's own
 * `fps` limit cannot skip frames there (a skipped XR frame is an empty picture). So with `fps`,
 * the page's frames themselves come at most that often: every animation-frame callback waits
 * for the next of `fps` slots a second, all those of one slot run together (as in one browser
 * frame). A real headset never loads this chunk. */
function limitAnimationFrames(fps) {
  const raf = window.requestAnimationFrame.bind(window);
  const periodMs = 1000 / fps;
  let queue = new Map(); // id -> callback, for the next slot
  let nextId = 1;
  let scheduled = false;
  let lastMs = -Infinity;
  const run = (t) => {
    scheduled = false;
    lastMs = performance.now();
    const batch = queue;
    queue = new Map();
    for (const cb of batch.values()) {
      try {
        cb(t);
      } catch (e) {
        // as the browser's own: the others of the slot still run, the error is still reported
        setTimeout(() => {
          throw e;
        });
      }
    }
  };
  const schedule = () => {
    if (scheduled) return;
    scheduled = true;
    // (2 ms early: the browser's frames come a little before or after their period)
    const waitMs = lastMs + periodMs - 2 - performance.now();
    if (waitMs > 0) setTimeout(() => raf(run), waitMs);
    else raf(run);
  };
  window.requestAnimationFrame = (cb) => {
    const id = nextId++;
    queue.set(id, cb);
    schedule();
    return id;
  };
  window.cancelAnimationFrame = (id) => {
    queue.delete(id);
  };
}

/** Installs window.hrcTest on the page of `app` (main.js's App, before its init); `maxFps` is
 * the page's `fps` as main.js read it (0: none), `emulatedXr` whether IWER is loaded. */
export function install(app, { maxFps = 0, emulatedXr = false } = {}) {
  if (emulatedXr && maxFps > 0) {
    limitAnimationFrames(maxFps);
    app.frameRateHz = () => maxFps; // and asks the bridge for no more frames than it draws
  }
  const hidden = new Map(); // what a test hides (hrcTest.hide): name -> reasons
  app.beforeRender = () => {
    if (hidden.size) applyHidden(app, hidden);
  };
  window.hrcTest = {
    /** The scene has arrived and every robot's URDF is loaded. */
    ready: () => !!window.hrcApp?.sceneMsg && window.hrcApp.robots.allLoaded() && window.hrcApp.frames > 0,
    /** The page's rules as numbers, so that a test states none of them again: the link is lost
     * after `silentBeats` heartbeats (every `heartbeatMs`) heard nothing, spanning `lostMs`;
     * a warning stays at least `messageMinMs` (net.js, hud.js). */
    constants: () => ({
      heartbeatMs: HEARTBEAT_MS,
      lostMs: LOST_MS,
      silentBeats: SILENT_BEATS,
      messageMinMs: MESSAGE_MIN_MS,
    }),
    /** Every message the page has shown, oldest first: [{text, kind, atMs}] (the last 50). */
    messages: () => window.hrcApp.hud.shown.map((m) => ({ ...m })),
    /** A world point [x, y, z] as CSS pixels of the page {x, y, visible}. */
    project: (xyz) => projectWith(window.hrcApp, xyz),
    /** A world point as the XR (local-floor) coordinates the calibration maps it to. */
    worldToXr: (xyz) => {
      const v = new THREE.Vector3(...xyz);
      window.hrcApp.root.localToWorld(v);
      return [v.x, v.y, v.z];
    },
    state: () => {
      const app = window.hrcApp;
      const objects = {};
      for (const [id, p] of app.world.parts) {
        objects[id] = {
          p: p.mesh.position.toArray(),
          q: p.mesh.quaternion.toArray(), // three.js's order: x, y, z, w
          holder: p.holder,
          placed: p.placed,
          grabbable: p.grabbable === true,
          visible: p.mesh.visible,
        };
      }
      const robots = {};
      for (const [id, r] of app.robots.robots) {
        robots[id] = { tcp: r.tcp, q: r.q, loaded: r.loaded, zone: r.zone };
      }
      const cues = {};
      for (const [id, c] of app.world.cues) cues[id] = { on: c.on, visible: c.obj.visible };
      return {
        role: app.role,
        run: app.run,
        task_t_s: app.taskT,
        connection: app.bridge ? app.bridge.state : 'none',
        frames: app.frames,
        xr: app.xr.active(),
        active_hand: app.desktop.active,
        parked: app.desktop.parked !== null, // the desktop hand waits at rest for the mouse
        panel_moving: !!app.hud.gliding, // the headset's panel glides after the gaze
        hands: app.xr.active() && app.lastXrHands ? app.lastXrHands : app.desktop.poses(),
        objects,
        robots,
        cues,
        events: app.events.map((e) => e.kind + (e.part ? `:${e.part}` : '')),
        sent: app.bridge ? app.bridge.sent : 0,
        screen: app.form?.screen ? { kind: app.form.screen.kind, id: app.form.screen.id } : null,
      };
    },
    /** Stops (true) or resumes (false) applying the bridge's frames, so that a screenshot and
     * the positions read before it agree; rendering, blinking and sending go on, the panel is
     * held too. 'scene': the frames stay held but the panel shows what the person does (a
     * calibration between two pictures of one moment). */
    freeze: (on) => {
      window.hrcApp.frozen = on === 'scene' ? 'scene' : !!on;
    },
    /** The labels on screen (CSS pixels): the parts' [{part, text, x0, y0, x1, y1}], the
     * names at the participant's targets not yet placed [{target, text, ..}] and the robots'
     * lit "Waiting.." labels [{cue, text, ..}] (in a headset as its first eye sees them, like
     * the pictures). */
    labels: () => {
      const app = window.hrcApp;
      const rect = (l) => {
        const pts = spriteCorners(eyeCamera(app), l).map((w) => pagePoint(app, w));
        const xs = pts.map((q) => q.x);
        const ys = pts.map((q) => q.y);
        return { x0: Math.min(...xs), y0: Math.min(...ys), x1: Math.max(...xs), y1: Math.max(...ys) };
      };
      const out = [];
      for (const [id, p] of app.world.parts) {
        if (p.label.visible) out.push({ part: id, text: p.spec.kind || id, ...rect(p.label) });
      }
      for (const [id, name] of app.world.targetNames) {
        if (name.visible) out.push({ target: id, text: id, ...rect(name) });
      }
      for (const [id, c] of app.world.cues) {
        if (c.spec.kind === 'waiting' && c.obj.visible) {
          out.push({ cue: id, text: c.obj.userData.text || c.spec.text, ...rect(c.obj) });
        }
      }
      return out;
    },
    /** The page's boxes over the view that are showing: {status, message, help: {x0, y0, x1, y1}}. */
    boxes: () => pageBoxes(['status', 'message', 'help']),
    /** Lights robot `rid`'s "Waiting.." label with `text` (null: off, its text the task's). */
    showWaiting: (rid, text) => {
      const app = window.hrcApp;
      app.testWaiting = { ...app.testWaiting, [rid]: text };
      const cue = app.world.cues.get(`waiting:${rid}`);
      if (cue) cue.on = !!text;
    },
    /** What the headset's status panel says (with the page's message), its lines unwrapped. */
    panelText: () => window.hrcApp.hud.saying ?? '',
    /** The session's screen: its kind, id, the page of a questionnaire, the answers so far,
     * whether it was sent, and its widgets (canvas px) [{id, kind, label, x, y, w, h,
     * disabled}]; null outside a session. */
    form: () => {
      const f = window.hrcApp?.form;
      if (!f || !f.screen) return null;
      return {
        kind: f.screen.kind,
        id: f.screen.id,
        title: f.screen.title || f.screen.questionnaire?.title || '',
        visible: f.visible(),
        page: f.page,
        keyboard: f.keyboardFor || null,
        answers: { ...f.answers },
        sent: f.sent,
        in_headset: !!window.hrcApp.formXr?.panel.visible,
        notice: f.notice || '', // what the form says of the link to the session
        // a text screen's page as drawn: {lines, bottom (px), pages, pageLine (px) or null}
        text: f.screen.kind === 'questionnaire' ? null : f.drawn || null,
        widgets: f.widgets.map(({ id, kind, label, x, y, w, h, disabled }) => ({ id, kind: kind || 'button', label, x, y, w, h, disabled: !!disabled })),
      };
    },
    /** A point of the form (canvas px) where a person would aim: page pixels {x, y} on the
     * desktop, XR (local-floor) coordinates {xr: [x, y, z]} on the headset's panel. */
    formPoint: (x, y) => {
      const app = window.hrcApp;
      if (app.formXr?.panel.visible) return { xr: app.formXr.worldPoint(x, y) };
      const r = app.form.canvas.getBoundingClientRect();
      return { x: r.left + (x * r.width) / FORM_W, y: r.top + (y * r.height) / FORM_H };
    },
    /** The robot target shown after a collision: {part, visible} or null. */
    goal: () => {
      const g = window.hrcApp.world.goal;
      return g ? { part: g.part, visible: g.obj.visible } : null;
    },
    /** Shows (true) or hides (false) the robots' protective zones (ssm). */
    showZones: (on) => window.hrcApp.robots.showZones(!!on),
    /** Freezes the page (as freeze(true)) at the first frame in which `part` is held by
     * `holder` and, with `cue`, that cue is lit, however late this page runs behind the trial.
     * The hold (physics's objects) and the cue (the orchestrator's) reach the bridge on two
     * subscriber threads: a frame may show the part held before its cue is lit. */
    freezeWhen: (part, holder, cue = null) => {
      window.hrcApp.freezeOn = { part, holder, cue };
    },
    /** The page's frame times (ms), oldest first: `intervals` between rendered frames, the
     * `work` of each (update + render call), its `render` call alone, and how many robots were
     * `moving` in it; `reset` clears them. */
    frameTimes: (reset = false) => {
      const app = window.hrcApp;
      const out = {
        intervals: [...app.frameMs],
        work: [...app.workMs],
        render: [...app.renderMs],
        moving: [...app.movingN],
      };
      if (reset) for (const a of [app.frameMs, app.workMs, app.renderMs, app.movingN]) a.length = 0;
      return out;
    },
    /** The last frame's draw calls, and the views it drew (an immersive frame draws one per eye). */
    drawCalls: () => {
      const app = window.hrcApp;
      const views = app.renderer.xr.isPresenting ? app.renderer.xr.getCamera().cameras.length : 1;
      return { calls: app.drawCalls, views };
    },
    /** Stops (true) or restarts (false) rendering, so that another page of the same browser
     * gets the CPU (software WebGL); the link to the bridge stays up. */
    pause: (on) => {
      const app = window.hrcApp;
      const loop = on ? null : (t, frame) => app.onFrame(t, frame);
      // in a headset only the headset's loop: three.js's renderer.setAnimationLoop would also
      // start its window loop beside it, and every frame would then be drawn twice
      if (app.renderer.xr.isPresenting) app.renderer.xr.setAnimationLoop(loop);
      else app.renderer.setAnimationLoop(loop);
    },
    /** Frames rendered so far (a test waits for new ones after a change). */
    rendered: () => window.hrcApp.rendered,
    /** Hides (true) or shows again (false) a thing by name (testObjects); `reason` keeps one
     * test's hiding apart from another's: a thing is hidden while any reason hides it. */
    hide: (name, on, reason = 'check') => {
      const app = window.hrcApp;
      testObjects(app, name); // an unknown name is an error now, not a silent no-op
      const reasons = hidden.get(name) || new Set();
      if (on) reasons.add(reason);
      else reasons.delete(reason);
      hidden.set(name, reasons);
    },
    /** World points where each thing should be seen: {name: [[x, y, z], ...]}. */
    probes: () => probePoints(window.hrcApp),
    /** The texts on screen with their angular size: [{what, em_deg, distance_m}]. */
    textSizes: () => textSizes(window.hrcApp),
    /** Holds the cues' blink lit (true) or unlit (false); null: they blink again. */
    flash: (phase) => {
      window.hrcApp.world.flashHeld = phase === null ? null : !!phase;
    },
    /** The headset panel's corners as page pixels and as angles from the eye's view direction
     * [{x, y, visible, az_deg, el_deg}] (null outside immersive mode). */
    panelCorners: () => {
      const app = window.hrcApp;
      const s = app.hud.sprite;
      if (!s || !s.visible) return null;
      const eye = eyeCamera(app);
      return [[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]].map(([x, y]) => {
        const local = new THREE.Vector3(x, y, 0);
        const v = s.localToWorld(local.clone()).applyMatrix4(eye.matrixWorldInverse); // eye frame
        const deg = THREE.MathUtils.radToDeg;
        return {
          ...projectWith(app, rootLocal(app, s, local)),
          az_deg: deg(Math.atan2(v.x, -v.z)),
          el_deg: deg(Math.atan2(v.y, -v.z)),
        };
      });
    },
  };
}
