// The robot arms: each loaded from its URDF as the bridge serves it (GET /robots/...), placed at
// its base, tinted in its colour and moved by the joint positions streamed in `frame`s.
import * as THREE from 'three';
import URDFLoader from 'urdf-loader';
import { setPose } from './frames.js';

// The URDF's own colours are kept for the dark/grey parts; its coloured links take the robot's
// colour, so the participant can tell the robots apart (and match them to their cues).
function tint(model, color) {
  const c = new THREE.Color(color);
  model.traverse((o) => {
    if (!o.isMesh) return;
    const mats = Array.isArray(o.material) ? o.material : [o.material];
    o.material = mats.map((m) => {
      const mat = new THREE.MeshStandardMaterial({ roughness: 0.6, metalness: 0.1 });
      const base = m?.color ? m.color.clone() : new THREE.Color('#bbb');
      const hsl = base.getHSL({});
      // saturated links (the URDF's accent colour) become the robot's colour
      mat.color = hsl.s > 0.3 ? c.clone() : base.lerp(c, 0.15);
      return mat;
    });
    if (o.material.length === 1) o.material = o.material[0];
  });
}

export class Robots {
  constructor(parentGroup, onError) {
    this.parent = parentGroup;
    this.onError = onError;
    this.robots = new Map(); // id -> {spec, model, pending q, tcp}
  }

  build(specs) {
    this.clear();
    for (const spec of specs || []) {
      const holder = new THREE.Group();
      holder.name = `robot:${spec.id}`;
      setPose(holder, spec.base?.xyz);
      holder.rotation.set(0, 0, THREE.MathUtils.degToRad(spec.base?.yaw_deg || 0));
      this.parent.add(holder);
      const entry = { spec, holder, model: null, q: null, tcp: null, loaded: false };
      this.robots.set(spec.id, entry);
      const loader = new URDFLoader();
      const url = new URL(spec.urdf_url, window.location.href);
      const base = url.href.slice(0, url.href.lastIndexOf('/'));
      loader.packages = () => base; // package:// meshes live beside the URDF on the bridge
      loader.load(
        url.href,
        (model) => {
          tint(model, spec.color || '#ff8800');
          holder.add(model);
          entry.model = model;
          entry.loaded = true;
          if (entry.q) this.setJoints(spec.id, entry.q);
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

  applyFrame(f) {
    for (const [id, st] of Object.entries(f.robots || {})) {
      if (st.q) this.setJoints(id, st.q);
      if (st.tcp) {
        const r = this.robots.get(id);
        if (r) r.tcp = st.tcp;
      }
    }
  }

  allLoaded() {
    return [...this.robots.values()].every((r) => r.loaded);
  }
}
