// Sounds synthesized in the page with WebAudio (no audio files): a chime when a part is placed,
// an alert on a collision, a click when the continue button is pressed. Every sound triggered is
// appended to `window.hrcAudioLog` ({sound, cause, t_ms, state}) for the browser tests.
let ctx = null;
window.hrcAudioLog = [];

function context() {
  if (!ctx) {
    const AC = window.AudioContext || window.webkitAudioContext;
    if (!AC) return null;
    ctx = new AC();
  }
  if (ctx.state === 'suspended') ctx.resume().catch(() => {});
  return ctx;
}

/** Called on the first user gesture: browsers start audio only after one. */
export function unlockAudio() {
  context();
}

function tone(ac, { type = 'sine', freq, start, dur, gain = 0.2, endFreq = null }) {
  const osc = ac.createOscillator();
  const g = ac.createGain();
  osc.type = type;
  osc.frequency.setValueAtTime(freq, start);
  if (endFreq) osc.frequency.linearRampToValueAtTime(endFreq, start + dur);
  g.gain.setValueAtTime(0.0001, start);
  g.gain.exponentialRampToValueAtTime(gain, start + 0.01);
  g.gain.exponentialRampToValueAtTime(0.0001, start + dur);
  osc.connect(g).connect(ac.destination);
  osc.start(start);
  osc.stop(start + dur + 0.02);
}

const SOUNDS = {
  // two bright notes, rising: something snapped into place
  chime(ac, t) {
    tone(ac, { freq: 880, start: t, dur: 0.25 });
    tone(ac, { freq: 1318.5, start: t + 0.09, dur: 0.35 });
  },
  // a harsh falling two-tone, twice: a collision
  alert(ac, t) {
    for (let i = 0; i < 2; i++) {
      tone(ac, { type: 'square', freq: 740, endFreq: 440, start: t + i * 0.22, dur: 0.18, gain: 0.15 });
    }
  },
  // a very short burst: the button's click
  click(ac, t) {
    tone(ac, { type: 'triangle', freq: 2000, endFreq: 600, start: t, dur: 0.04, gain: 0.3 });
  },
};

export function play(sound, cause = '') {
  const ac = context();
  window.hrcAudioLog.push({ sound, cause, t_ms: performance.now(), state: ac ? ac.state : 'none' });
  if (!ac) return;
  SOUNDS[sound](ac, ac.currentTime + 0.01);
}

/** The sound of a task event, if it has one. */
export function soundForEvent(kind) {
  return { part_placed: 'chime', collision: 'alert', button_pressed: 'click' }[kind] || null;
}
