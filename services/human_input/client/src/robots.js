// The robot arms: each loaded from its URDF as the bridge serves it (GET /robots/...), placed at
// its base, tinted in its colour and moved by the joint positions streamed in `frame`s.
import * as THREE from 'three';
import URDFLoader from 'urdf-loader';
import { OBJLoader } from 'three/addons/loaders/OBJLoader.js';
import { mergeGeometries } from 'three/addons/utils/BufferGeometryUtils.js';
import { litMaterial, painted } from './batch.js';
import { setPose } from './frames.js';

// urdf-loader reads STL and COLLADA; OBJ (pybullet's data folder writes its meshes so) here.
function loadMesh(path, manager, material, done) {
  if (/\.(stl|dae)$/i.test(path)) {
    URDFLoader.prototype.defaultMeshLoader.call(null, path, manager, material, done);
    return;
  }
  if (!/\.obj$/i.test(path)) {
    done(null, new Error(`no loader for ${path} (STL, COLLADA and OBJ are read)`));
    return;
  }
  new OBJLoader(manager).load(
    path,
    (group) => {
      // Faces only: some makers' OBJ files carry stray line elements (the Panda's link5/6),
      // which three draws as white lines over the arm.
      const strays = [];
      group.traverse((o) => {
        if (o.isLine || o.isPoints) strays.push(o);
        else if (o.isMesh && material) o.material = material;
      });
      for (const o of strays) o.parent.remove(o);
      done(group);
    },
    null,
    (err) => done(null, err),
  );
}

// The URDF's own colours are kept for the dark/grey parts; its coloured links take the robot's
// colour, so the participant can tell the robots apart (and match them to their cues).
function tint(model, color) {
  const c = new THREE.Color(color);
  model.traverse((o) => {
    if (!o.isMesh) return;
    const mats = Array.isArray(o.material) ? o.material : [o.material];
    o.material = mats.map((m) => {
      const mat = litMaterial();
      const base = m?.color ? m.color.clone() : new THREE.Color('#bbb');
      const hsl = base.getHSL({});
      // saturated links (the URDF's accent colour) and white ones (a maker's shells, e.g. the
      // Panda's) become the robot's colour; the grey ones take a third of it, so a base stands
      // out from a grey floor and reads as this robot's
      mat.color = hsl.s > 0.3 || hsl.l > 0.85 ? c.clone() : base.lerp(c, 0.35);
      return mat;
    });
    if (o.material.length === 1) o.material = o.material[0];
  });
}

/** One mesh per link (a draw call each, not one per visual): the link's own visuals, in their
 * tinted colours as vertex colours, merged in the link's frame. Visuals of other kinds (lines)
 * and meshes that come later stay as they are. */
function mergePerLink(model) {
  model.updateMatrixWorld(true);
  for (const link of Object.values(model.links)) {
    const own = [];
    link.traverse((o) => {
      if (!o.isMesh || Array.isArray(o.material)) return;
      let up = o.parent;
      while (up && !up.isURDFLink) up = up.parent;
      if (up === link) own.push(o);
    });
    if (own.length === 1) own[0].name = `link:${link.name}`; // (the probes of the tests find it)
    if (own.length < 2) continue;
    const toLink = new THREE.Matrix4().copy(link.matrixWorld).invert();
    const pieces = own.map((o) => {
      let g = o.geometry.index ? o.geometry.toNonIndexed() : o.geometry.clone();
      for (const name of Object.keys(g.attributes)) if (name !== 'position' && name !== 'normal') g.deleteAttribute(name);
      if (!g.attributes.normal) g.computeVertexNormals();
      g.applyMatrix4(new THREE.Matrix4().multiplyMatrices(toLink, o.matrixWorld));
      return painted(g, o.material.color || '#bbb');
    });
    const merged = mergeGeometries(pieces, false);
    for (const g of pieces) g.dispose();
    if (!merged) continue; // shapes that do not merge stay as they are
    for (const o of own) {
      o.parent.remove(o);
      o.geometry.dispose();
    }
    const mesh = new THREE.Mesh(
      merged,
      litMaterial({ vertexColors: true }),
    );
    mesh.name = `link:${link.name}`;
    link.add(mesh);
  }
}

// The protective zone (safety_policy = "ssm"), drawn as the researcher's view draws it: a
// translucent sphere of the zone's radius around each link origin of the arm, coloured by state.
// The spheres of one arm are blended once per pixel (the stencil keeps a second layer out), so
// the zone reads as one volume and the arm inside it keeps its colour; no depth writes, so the
// arm and the parts behind stay visible.
const UNIT_SPHERE = new THREE.SphereGeometry(1, 24, 16);

function zoneMaterial(style, ref) {
  return new THREE.MeshBasicMaterial({
    color: style.colors.normal,
    transparent: true,
    opacity: style.opacity,
    depthWrite: false,
    stencilWrite: true,
    stencilRef: ref,
    stencilFunc: THREE.NotEqualStencilFunc,
    stencilZPass: THREE.ReplaceStencilOp,
  });
}

export class Robots {
  constructor(parentGroup, onError) {
    this.parent = parentGroup;
    this.onError = onError;
    this.robots = new Map(); // id -> {spec, model, pending q, tcp, zone}
    this.zoneStyle = null; // the scene's ssm_zone: colours by state and opacity
    this.baseUrl = ''; // where the robots' files are served ('': the page's own server)
  }

  build(specs, zoneStyle) {
    this.clear();
    this.zoneStyle = zoneStyle || null;
    for (const spec of specs || []) {
      const holder = new THREE.Group();
      holder.name = `robot:${spec.id}`;
      setPose(holder, spec.base?.xyz);
      holder.rotation.set(0, 0, THREE.MathUtils.degToRad(spec.base?.yaw_deg || 0));
      this.parent.add(holder);
      const entry = { spec, holder, model: null, q: null, tcp: null, loaded: false, zone: null };
      this.robots.set(spec.id, entry);
      // The URDF is parsed first and its meshes arrive later: the robot is shown once it has
      // them all (a half-loaded arm would be tinted and merged without its meshes). Counted
      // here, not by a LoadingManager: three's FileLoader joins requests for a URL already on
      // its way (two robots from one URDF) without telling the second robot's manager.
      const loader = new URDFLoader();
      const url = new URL(spec.urdf_url, this.baseUrl || window.location.href);
      const base = url.href.slice(0, url.href.lastIndexOf('/'));
      // package://NAME/x is asked for as /robots/NAME/x: the bridge finds it around the URDF
      loader.packages = (pkg) => `${base}/${pkg}`;
      let parsed = null;
      let pending = 0;
      const failed = [];
      const finish = () => {
        if (!parsed || pending > 0 || entry.model) return;
        if (failed.length) {
          this.onError?.(`robot ${spec.id}: cannot load ${failed.join(', ')}`);
        }
        if (spec.tint !== false) tint(parsed, spec.color || '#ff8800');
        mergePerLink(parsed);
        holder.add(parsed);
        entry.model = parsed;
        entry.loaded = true;
        if (entry.q) this.setJoints(spec.id, entry.q);
        if (entry.zone) this.setZone(spec.id, entry.zone);
      };
      loader.loadMeshCb = (path, manager, material, done) => {
        pending += 1;
        loadMesh(path, manager, material, (mesh, err) => {
          done(mesh, err);
          pending -= 1;
          if (err || !mesh) failed.push(path);
          finish();
        });
      };
      loader.load(
        url.href,
        (model) => {
          parsed = model;
          finish();
        },
        undefined,
        (err) => this.onError?.(`robot ${spec.id}: cannot load ${spec.urdf_url}: ${err}`),
      );
    }
  }

  clear() {
    for (const r of this.robots.values()) this.parent.remove(r.holder);
    this.robots.clear();
  }

  setJoints(id, q) {
    const r = this.robots.get(id);
    if (!r) return;
    r.q = q;
    if (!r.model) return;
    const names = r.spec.joint_names || [];
    for (let i = 0; i < names.length && i < q.length; i++) {
      r.model.setJointValue(names[i], q[i]);
    }
  }

  /** zone: {radius, state} of a frame's `zones`; the spheres follow the links they hang on. */
  setZone(id, zone) {
    const r = this.robots.get(id);
    if (!r || !this.zoneStyle) return;
    r.zone = zone;
    if (!r.model) return;
    if (!r.zoneMeshes) {
      const index = [...this.robots.keys()].indexOf(id) + 1; // 1.. : its stencil value
      r.zoneMaterial = zoneMaterial(this.zoneStyle, index);
      r.zoneMeshes = Object.values(r.model.links).map((link) => {
        const m = new THREE.Mesh(UNIT_SPHERE, r.zoneMaterial);
        m.name = `zone:${id}`;
        m.renderOrder = index; // after the opaque arms, one arm's spheres together
        link.add(m);
        return m;
      });
    }
    const color = this.zoneStyle.colors[zone.state] || this.zoneStyle.colors.normal;
    r.zoneMaterial.color.set(color);
    for (const m of r.zoneMeshes) m.scale.setScalar(Math.max(zone.radius, 1e-3));
  }

  applyFrame(f) {
    for (const [id, st] of Object.entries(f.robots || {})) {
      if (st.q) this.setJoints(id, st.q);
      if (st.tcp) {
        const r = this.robots.get(id);
        if (r) r.tcp = st.tcp;
      }
    }
    for (const [id, zone] of Object.entries(f.zones || {})) this.setZone(id, zone);
  }

  /** Shows or hides every protective zone (the browser tests compare the two pictures). */
  showZones(on) {
    for (const r of this.robots.values()) for (const m of r.zoneMeshes || []) m.visible = on;
  }

  /** The zone as last received (tests, HUD): {radius, state} or null. */
  zoneOf(id) {
    return this.robots.get(id)?.zone || null;
  }

  /** How many robots' joints changed since the last call. */
  movedSinceLastAsked() {
    let n = 0;
    for (const r of this.robots.values()) {
      if (r.q && r.seenQ && r.q.some((v, i) => Math.abs(v - r.seenQ[i]) > 1e-6)) n++;
      r.seenQ = r.q;
    }
    return n;
  }

  allLoaded() {
    return [...this.robots.values()].every((r) => r.loaded);
  }
}
