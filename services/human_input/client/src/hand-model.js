// A hand as the participant sees it: a slim palm, four fingers and a thumb (one mesh), open or
// closed with the grip. Life-size (a palm 7 cm wide): in a headset a controller held near the face
// must not fill the view, and on a desktop the hand must read as a hand, not a block.
import * as THREE from 'three';
import { mergeGeometries } from 'three/addons/utils/BufferGeometryUtils.js';

const PALM = [0.07, 0.075, 0.018]; // x across, y along the fingers, z thickness
const FINGER = [0.014, 0.06, 0.014];
const THUMB = [0.016, 0.045, 0.014];

function piece(size, x, y, z, rotX = 0, rotZ = 0) {
  const g = new THREE.BoxGeometry(...size);
  g.deleteAttribute('uv');
  // a finger turns about its root (its -y end), not its middle
  g.translate(0, size[1] / 2, 0);
  g.applyMatrix4(new THREE.Matrix4().makeRotationFromEuler(new THREE.Euler(rotX, 0, rotZ, 'ZXY')));
  g.translate(x, y, z);
  return g;
}

/** The hand's geometry, fingers along +y (an identity hand's pose), palm down: `closed` curls
 * the fingers under the palm. `side` 'left' or 'right' puts the thumb on the inner side. */
export function handGeometry(side, closed) {
  const pieces = [];
  const palm = new THREE.BoxGeometry(...PALM);
  palm.deleteAttribute('uv');
  pieces.push(palm);
  const curl = closed ? -1.9 : 0; // about x: the fingers bend down and back
  const gap = PALM[0] / 4;
  for (let i = 0; i < 4; i++) {
    const x = -PALM[0] / 2 + gap / 2 + i * gap;
    const length = i === 0 || i === 3 ? 0.85 : 1; // the outer fingers are shorter
    pieces.push(piece([FINGER[0], FINGER[1] * length, FINGER[2]], x, PALM[1] / 2, 0, curl));
  }
  const inner = side === 'right' ? -1 : 1; // a right palm down has its thumb on the left (-x)
  pieces.push(piece(THUMB, inner * PALM[0] / 2, -0.01, 0, closed ? -1.2 : 0, inner * (closed ? 0.3 : 0.7)));
  const g = mergeGeometries(pieces, false);
  for (const p of pieces) p.dispose();
  return g;
}
