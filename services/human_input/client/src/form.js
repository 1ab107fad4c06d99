// The session's screens between trials (consent, instructions, questionnaires, ready, break),
// drawn on one 2D canvas with their widgets and hit-tested on it: the desktop shows the canvas
// over the page (mouse, keyboard), the headset as a panel answered with the controller's ray
// and trigger (form-xr.js). One layout and one set of widgets for both.
//
// A screen (from the session, docs/client-protocol.md "Sessions"): {id, kind, title, text,
// questionnaire, problems, break_s, progress}. What the participant does goes to `onSend`.

export const FORM_W = 1024;
export const FORM_H = 680;
const PAD = 40;
const FONT = 'system-ui, sans-serif';
const BODY_PX = 24;
const BOTTOM = FORM_H - 96; // the buttons' row
const KEYS = ['1234567890', 'qwertyuiop', 'asdfghjkl\'', 'zxcvbnm,.?'];

/** Lines of `text` that fit `width` px in the context's font (words kept whole). */
function wrapPx(ctx, text, width) {
  const out = [];
  for (const para of String(text).split('\n')) {
    let cur = '';
    for (const word of para.split(/\s+/).filter(Boolean)) {
      const next = cur ? `${cur} ${word}` : word;
      if (cur && ctx.measureText(next).width > width) {
        out.push(cur);
        cur = word;
      } else cur = next;
    }
    out.push(cur);
  }
  return out;
}

/** Markdown as the screens need it: headings, paragraphs, bullet lists; **, _ and ` dropped.
 * As in Markdown, the lines of a paragraph (or of a list item) are one text: the file's own
 * line breaks are not the screen's. */
function markdownBlocks(md) {
  const blocks = [];
  for (const raw of String(md || '').split('\n')) {
    const line = raw.replace(/\*\*|__|`/g, '').replace(/(^|\s)[*_](\S[^*_]*)[*_]/g, '$1$2');
    const h = line.match(/^(#{1,6})\s+(.*)$/);
    const prev = blocks[blocks.length - 1];
    if (h) blocks.push({ kind: 'h', text: h[2] });
    else if (/^\s*[-*]\s+/.test(line)) blocks.push({ kind: 'li', text: line.replace(/^\s*[-*]\s+/, '\u2022 ') });
    else if (!line.trim()) blocks.push({ kind: 'gap' });
    else if (prev && (prev.kind === 'p' || prev.kind === 'li')) prev.text += ` ${line.trim()}`;
    else blocks.push({ kind: 'p', text: line.trim() });
  }
  return blocks;
}

export class FormView {
  constructor({ onSend }) {
    this.canvas = document.createElement('canvas');
    this.canvas.width = FORM_W;
    this.canvas.height = FORM_H;
    this.ctx = this.canvas.getContext('2d');
    this.onSend = onSend;
    this.screen = null;
    this.widgets = [];
    this.hover = null; // [x, y] of the pointer (canvas px), or null
    this.version = 0; // bumped at every redraw (the headset's texture follows it)
  }

  /** A new screen from the session (the same id again: only its problems are new). */
  show(screen) {
    const same = this.screen && screen && this.screen.id === screen.id;
    this.screen = screen;
    if (!same) {
      // a questionnaire comes back with the answers already given (a closed tab, a crash)
      this.answers = { ...(screen?.draft || {}) };
      this.page = 0;
      this.textPage = 0;
      this.focus = null; // a text item taking the keys
      this.sent = false;
      this.shownAt = performance.now();
    } else {
      this.sent = false; // asked again (problems): the answers stay
    }
    this.layout();
  }

  /** A line about the link to the session ('' : none), drawn on every screen until cleared. */
  setNotice(text) {
    if (this.notice === text) return;
    this.notice = text;
    this.layout();
  }

  visible() {
    return !!this.screen && !['trial'].includes(this.screen.kind);
  }

  // ---------------------------------------------------------------- input
  /** A click (canvas px). */
  click(x, y) {
    const w = this.widgets.find((it) => x >= it.x && x <= it.x + it.w && y >= it.y && y <= it.y + it.h);
    if (!w || w.disabled) return false;
    w.act(x, y);
    this.layout();
    this.queueDraft();
    return true;
  }

  /** Each answer is kept by the session as it is given (sent a moment after the last change). */
  queueDraft() {
    const s = this.screen;
    if (s?.kind !== 'questionnaire' || this.sent || this.draftTimer) return;
    this.draftTimer = setTimeout(() => {
      this.draftTimer = null;
      if (this.screen !== s || this.sent) return;
      this.onSend({ type: 'draft', screen: s.id, questionnaire: s.questionnaire.id, answers: { ...this.answers } });
    }, 300);
  }

  pointer(xy) {
    const was = this.hover;
    this.hover = xy;
    if (String(was) !== String(xy)) this.layout();
  }

  /** A key from the desktop's keyboard: typed into the focused text item. */
  key(e) {
    if (!this.focus) return false;
    const cur = this.answers[this.focus] || '';
    if (e.key === 'Backspace') this.answers[this.focus] = cur.slice(0, -1);
    else if (e.key === 'Enter' || e.key === 'Escape') this.focus = null;
    else if (e.key.length === 1 && cur.length < 2000) this.answers[this.focus] = cur + e.key;
    else return false;
    this.layout();
    this.queueDraft();
    return true;
  }

  send(msg) {
    if (this.sent) return;
    // not sent (the link is down): the button stays, the participant can press it again
    this.sent = this.onSend({ ...msg, screen: this.screen.id }) !== false;
  }

  // ---------------------------------------------------------------- layout + drawing
  layout() {
    const ctx = this.ctx;
    this.widgets = [];
    ctx.fillStyle = '#1c2430';
    ctx.fillRect(0, 0, FORM_W, FORM_H);
    const s = this.screen;
    if (!s) return;
    ctx.fillStyle = '#9fb3c8';
    ctx.font = `18px ${FONT}`;
    // skipped trials are not done: the participant did not do them
    const skipped = s.progress?.skipped ? ` (${s.progress.skipped} skipped)` : '';
    const prog = s.progress ? `trials done: ${s.progress.done} of ${s.progress.total}${skipped}` : '';
    ctx.fillText(prog, PAD, 34);
    if (this.notice) {
      // the link to the session is down: said where the participant reads, on the form itself
      ctx.fillStyle = '#f0a040';
      ctx.font = `bold 18px ${FONT}`;
      ctx.textAlign = 'right';
      ctx.fillText(this.notice, FORM_W - PAD, 34);
      ctx.textAlign = 'left';
    }
    ctx.fillStyle = '#ffffff';
    ctx.font = `bold 34px ${FONT}`;
    ctx.fillText(s.title || s.questionnaire?.title || '', PAD, 84);
    const draw = {
      consent: () => this.drawText(s.text, [['I do not agree', () => this.send({ type: 'consent', accepted: false }), 'no'], ['I agree', () => this.send({ type: 'consent', accepted: true }), 'yes']]),
      text: () => this.drawText(s.text, [['Continue', () => this.send({ type: 'continue' }), 'continue']]),
      ready: () => this.drawReady(),
      questionnaire: () => this.drawQuestionnaire(),
    }[s.kind];
    if (draw) draw();
    else this.drawText(s.text || '', []);
    if (this.hover) {
      ctx.fillStyle = '#ffdd33';
      ctx.beginPath();
      ctx.arc(this.hover[0], this.hover[1], 7, 0, 2 * Math.PI);
      ctx.fill();
    }
    this.version++;
  }

  button(x, y, w, h, label, act, { id = label, disabled = false, on = false, size = 24 } = {}) {
    const ctx = this.ctx;
    const hot = this.hover && this.hover[0] >= x && this.hover[0] <= x + w && this.hover[1] >= y && this.hover[1] <= y + h;
    ctx.fillStyle = disabled ? '#3a4350' : on ? '#2a6cd6' : hot ? '#45607f' : '#33475e';
    ctx.fillRect(x, y, w, h);
    ctx.strokeStyle = on ? '#9cc2ff' : '#5d7590';
    ctx.lineWidth = 2;
    ctx.strokeRect(x + 1, y + 1, w - 2, h - 2);
    ctx.fillStyle = disabled ? '#7d8896' : '#ffffff';
    ctx.font = `${size}px ${FONT}`;
    const tw = ctx.measureText(label).width;
    ctx.fillText(label, x + (w - tw) / 2, y + h / 2 + size * 0.35);
    this.widgets.push({ id, x, y, w, h, act, disabled, label });
  }

  /** Paragraphs (paged when long) and the buttons; the last page carries `buttons`
   * [[label, act, id]]. */
  drawText(md, buttons) {
    const ctx = this.ctx;
    const lines = [];
    for (const b of markdownBlocks(md)) {
      if (b.kind === 'gap') {
        lines.push({ text: '', px: 12 });
        continue;
      }
      const px = b.kind === 'h' ? 28 : BODY_PX;
      ctx.font = `${b.kind === 'h' ? 'bold ' : ''}${px}px ${FONT}`;
      for (const l of wrapPx(ctx, b.text, FORM_W - 2 * PAD)) lines.push({ text: l, px, bold: b.kind === 'h' });
    }
    const pages = [[]];
    let h = 0;
    // the text ends above "page k of n" (and the buttons below it)
    const room = BOTTOM - 130 - 44;
    for (const l of lines) {
      const lh = l.px * 1.4;
      if (h + lh > room && pages[pages.length - 1].length) {
        pages.push([]);
        h = 0;
      }
      pages[pages.length - 1].push(l);
      h += lh;
    }
    this.textPage = Math.min(this.textPage, pages.length - 1);
    let y = 130;
    ctx.fillStyle = '#e8eef5';
    for (const l of pages[this.textPage]) {
      ctx.font = `${l.bold ? 'bold ' : ''}${l.px}px ${FONT}`;
      y += l.px * 1.4;
      ctx.fillText(l.text, PAD, y);
    }
    // what is on the page (the browser tests read it): its lines, where the last one ends
    this.drawn = { lines: pages[this.textPage].map((l) => l.text), bottom: y, pages: pages.length, pageLine: null };
    const last = this.textPage === pages.length - 1;
    if (pages.length > 1) {
      ctx.fillStyle = '#9fb3c8';
      ctx.font = `18px ${FONT}`;
      ctx.fillText(`page ${this.textPage + 1} of ${pages.length}`, PAD, BOTTOM - 16);
      this.drawn.pageLine = BOTTOM - 16 - 18; // the top of its letters
      if (this.textPage > 0) this.button(PAD, BOTTOM, 160, 60, 'Back', () => { this.textPage--; }, { id: 'back' });
    }
    if (!last) {
      this.button(FORM_W - PAD - 200, BOTTOM, 200, 60, 'Read on', () => { this.textPage++; }, { id: 'more' });
      return;
    }
    let x = FORM_W - PAD;
    for (const [label, act, id, off = false] of [...buttons].reverse()) {
      const w = Math.max(200, label.length * 15 + 40);
      x -= w;
      this.button(x, BOTTOM, w, 60, label, act, { id, disabled: this.sent || off });
      x -= 24;
    }
  }

  drawReady() {
    const s = this.screen;
    const left = Math.max(0, (s.break_s || 0) - (performance.now() - this.shownAt) / 1000);
    const text = left > 0
      ? `${s.text}\n\nTake a break: ${Math.ceil(left)} s, then Start.`
      : `${s.text}\n\nPress Start when you are ready.`;
    this.drawText(text, [['Start', () => this.send({ type: 'start' }), 'start', left > 0]]);
    if (left > 0) this.breakTimer = this.breakTimer || setTimeout(() => { this.breakTimer = null; this.layout(); }, 500);
  }

  // ---------------------------------------------------------------- questionnaires
  /** The questionnaire's items in pages that fit the panel. */
  pages(items) {
    const height = { scale: 118, likert: 112, choice: 104, text: 120 };
    const pages = [[]];
    let h = 0;
    for (const it of items) {
      const ih = height[it.kind] || 110;
      if (h + ih > BOTTOM - 150 && pages[pages.length - 1].length) {
        pages.push([]);
        h = 0;
      }
      pages[pages.length - 1].push(it);
      h += ih;
    }
    return pages;
  }

  /** Asked, with the answers given so far (`show_if`: each named earlier item's answer is one
   * of those listed; branching). */
  shown(it) {
    return Object.entries(it.show_if || {}).every(([id, values]) => values.includes(this.answers[id]));
  }

  answered(it) {
    const v = this.answers[it.id];
    return v !== undefined && v !== null && v !== '';
  }

  drawQuestionnaire() {
    const ctx = this.ctx;
    const q = this.screen.questionnaire;
    if (this.keyboardFor) return this.drawKeyboard();
    const items = q.items.filter((it) => this.shown(it));
    const pages = this.pages(items);
    this.page = Math.min(this.page, pages.length - 1);
    let y = 112;
    ctx.fillStyle = '#c9d6e3';
    ctx.font = `20px ${FONT}`;
    const intro = this.page === 0 && q.intro ? q.intro : '';
    if (intro) {
      for (const l of wrapPx(ctx, intro, FORM_W - 2 * PAD)) {
        y += 26;
        ctx.fillText(l, PAD, y);
      }
    }
    y += 14;
    for (const it of pages[this.page]) y = this.drawItem(it, y);
    const problems = this.screen.problems || [];
    if (problems.length) {
      ctx.fillStyle = '#ffb0a0';
      ctx.font = `18px ${FONT}`;
      ctx.fillText(`Please check: ${problems.slice(0, 2).join('; ')}`.slice(0, 90), PAD, BOTTOM - 14);
    }
    ctx.fillStyle = '#9fb3c8';
    ctx.font = `18px ${FONT}`;
    if (pages.length > 1) ctx.fillText(`page ${this.page + 1} of ${pages.length}`, FORM_W / 2 - 50, BOTTOM + 36);
    if (this.page > 0) this.button(PAD, BOTTOM, 160, 60, 'Back', () => { this.page--; }, { id: 'back' });
    const pageDone = pages[this.page].every((it) => !it.required || this.answered(it));
    const last = this.page === pages.length - 1;
    const label = last ? 'Submit' : 'Next';
    this.button(FORM_W - PAD - 200, BOTTOM, 200, 60, label, () => {
      if (!last) {
        this.page++;
        return;
      }
      const answers = {};
      for (const it of items) if (this.answered(it)) answers[it.id] = this.answers[it.id];
      this.send({ type: 'answers', questionnaire: q.id, answers });
    }, { id: last ? 'submit' : 'next', disabled: !pageDone || this.sent });
  }

  drawItem(it, y0) {
    const ctx = this.ctx;
    ctx.fillStyle = this.answered(it) || !it.required ? '#ffffff' : '#ffe9a8';
    ctx.font = `21px ${FONT}`;
    const lines = wrapPx(ctx, it.text, FORM_W - 2 * PAD);
    let y = y0;
    for (const l of lines.slice(0, 2)) {
      y += 26;
      ctx.fillText(l, PAD, y);
    }
    y += 10;
    const x0 = PAD;
    const width = FORM_W - 2 * PAD;
    if (it.kind === 'scale') {
      // 21 marks, 0..100 in fives, between the two anchors (NASA-TLX)
      const top = y;
      const h = 36;
      ctx.strokeStyle = '#c9d6e3';
      ctx.lineWidth = 2;
      ctx.beginPath();
      ctx.moveTo(x0, top + h);
      ctx.lineTo(x0 + width, top + h);
      for (let i = 0; i <= 20; i++) {
        const x = x0 + (i * width) / 20;
        ctx.moveTo(x, top + (i === 10 ? 0 : i % 2 === 0 ? 10 : 20));
        ctx.lineTo(x, top + h);
      }
      ctx.stroke();
      const v = this.answers[it.id];
      if (v !== undefined) {
        ctx.fillStyle = '#2a9df4';
        const x = x0 + (v / 100) * width;
        ctx.fillRect(x - 7, top - 2, 14, h + 4);
      }
      ctx.fillStyle = '#c9d6e3';
      ctx.font = `18px ${FONT}`;
      ctx.fillText(it.anchors?.[0] || '', x0, top + h + 24);
      const right = it.anchors?.[1] || '';
      ctx.fillText(right, x0 + width - ctx.measureText(right).width, top + h + 24);
      this.widgets.push({
        id: `${it.id}`,
        kind: 'scale',
        x: x0 - 10, y: top - 6, w: width + 20, h: h + 12,
        act: (x) => { this.answers[it.id] = Math.round(Math.min(20, Math.max(0, ((x - x0) / width) * 20))) * 5; },
        value: (v2) => ({ x: x0 + (v2 / 100) * width, y: top + h / 2 }),
      });
      return top + h + 40;
    }
    if (it.kind === 'likert' || it.kind === 'choice') {
      const values = it.kind === 'likert'
        ? Array.from({ length: it.points }, (_, i) => it.start + i)
        : it.options;
      const labels = it.kind === 'likert'
        ? values.map((v, i) => (it.labels && it.labels.length ? it.labels[i] : String(v)))
        : it.options;
      const gap = 10;
      const bw = Math.min(200, (width - gap * (values.length - 1)) / values.length);
      values.forEach((v, i) => {
        const x = x0 + i * (bw + gap);
        this.button(x, y, bw, 44, labels[i], () => { this.answers[it.id] = v; }, {
          id: `${it.id}=${v}`,
          on: this.answers[it.id] === v,
          size: labels[i].length > 12 ? 16 : 20,
        });
      });
      if (it.kind === 'likert' && !(it.labels && it.labels.length) && it.anchors) {
        ctx.fillStyle = '#c9d6e3';
        ctx.font = `16px ${FONT}`;
        ctx.fillText(it.anchors[0] || '', x0, y + 64);
        const right = it.anchors[1] || '';
        const xr = x0 + values.length * (bw + gap) - gap;
        ctx.fillText(right, xr - ctx.measureText(right).width, y + 64);
      }
      return y + 78;
    }
    // free text: typed on the desktop's keyboard, or on the panel's keyboard in the headset
    const focused = this.focus === it.id;
    ctx.fillStyle = focused ? '#f4f8ff' : '#dfe6ee';
    ctx.fillRect(x0, y, width, 50);
    ctx.fillStyle = '#111';
    ctx.font = `20px ${FONT}`;
    const val = String(this.answers[it.id] || '');
    const shown = val.length > 70 ? `\u2026${val.slice(-70)}` : val;
    ctx.fillText(shown + (focused ? '|' : ''), x0 + 10, y + 32);
    if (!val && !focused) {
      ctx.fillStyle = '#667';
      ctx.fillText('(click or point here to type)', x0 + 10, y + 32);
    }
    this.widgets.push({
      id: it.id,
      kind: 'text',
      x: x0, y, w: width, h: 50,
      act: () => {
        this.focus = it.id;
        if (this.keyboardWanted) this.keyboardFor = it.id;
      },
    });
    return y + 70;
  }

  /** The panel's own keyboard, for a text item in the headset. */
  drawKeyboard() {
    const ctx = this.ctx;
    const id = this.keyboardFor;
    const item = this.screen.questionnaire.items.find((it) => it.id === id);
    ctx.fillStyle = '#ffffff';
    ctx.font = `21px ${FONT}`;
    ctx.fillText(item ? item.text.slice(0, 80) : id, PAD, 126);
    ctx.fillStyle = '#f4f8ff';
    ctx.fillRect(PAD, 142, FORM_W - 2 * PAD, 50);
    ctx.fillStyle = '#111';
    const val = String(this.answers[id] || '');
    ctx.fillText(`${val.length > 70 ? `\u2026${val.slice(-70)}` : val}|`, PAD + 10, 175);
    const kw = 84;
    KEYS.forEach((row, r) => {
      const x0 = PAD + r * 20;
      [...row].forEach((ch, i) => {
        this.button(x0 + i * (kw + 8), 212 + r * 68, kw, 58, ch, () => {
          if (val.length < 2000) this.answers[id] = (this.answers[id] || '') + ch;
        }, { id: `key:${ch}`, size: 26 });
      });
    });
    const y = 212 + 4 * 68;
    this.button(PAD, y, 420, 58, 'space', () => { this.answers[id] = `${this.answers[id] || ''} `; }, { id: 'key:space' });
    this.button(PAD + 440, y, 200, 58, '\u2190 delete', () => { this.answers[id] = String(this.answers[id] || '').slice(0, -1); }, { id: 'key:back' });
    this.button(FORM_W - PAD - 200, BOTTOM, 200, 60, 'Done', () => {
      this.keyboardFor = null;
      this.focus = null;
    }, { id: 'key:done' });
  }
}
