// The scene's obstacles and objects as three.js meshes (z up, metres), from the scene JSON of
// `GET /v1/scenes/{name}`: bodies with a pose and shapes (box, cylinder, sphere, capsule, mesh).
// A mesh shape is fetched as the server loaded it (`GET /v1/scenes/{name}/meshes/{list}/{i}/{k}`,
// OBJ text, scale applied) and read with three.js's OBJLoader.
import * as THREE from 'three';
import { OBJLoader } from 'three/examples/jsm/loaders/OBJLoader.js';

/** A three.js matrix of a manyhands pose JSON (`position` + `rpy` (URDF fixed-axis X-Y-Z) or `quat_xyzw`). */
export function poseMatrix(p) {
  const m = new THREE.Matrix4();
  if (!p) return m;
  const t = p.position || [0, 0, 0];
  let q = new THREE.Quaternion();
  if (p.quat_xyzw) {
    const [x, y, z, w] = p.quat_xyzw;
    q.set(x, y, z, w).normalize();
  } else if (p.rpy) {
    q = new THREE.Quaternion().setFromEuler(new THREE.Euler(p.rpy[0], p.rpy[1], p.rpy[2], 'ZYX'));
  }
  m.compose(new THREE.Vector3(t[0], t[1], t[2]), q, new THREE.Vector3(1, 1, 1));
  return m;
}

/** A group filled later with the mesh read from `url` (OBJ text), drawn in `material`. */
function meshShape(url, material, ctx, where) {
  const group = new THREE.Group();
  ctx.pending.push(
    ctx.fetchText(url).then(
      (text) => {
        const parsed = new OBJLoader().parse(text);
        parsed.traverse((o) => {
          if (!o.isMesh) return;
          if (!o.geometry.getAttribute('normal')) o.geometry.computeVertexNormals();
          o.material = material;
        });
        group.add(parsed);
      },
      (e) => ctx.notes.push(`${where}: mesh not drawn (${e.message || e})`),
    ),
  );
  return group;
}

/** Mesh of one shape JSON, or null (with the reason pushed to `notes`) for what is not drawn. */
function shapeMesh(g, material, ctx, where, url) {
  const notes = ctx.notes;
  let geom;
  let alongZ = false;
  let mesh;
  switch (g.type) {
    case 'box': {
      const h = g.half_extents;
      geom = new THREE.BoxGeometry(2 * h[0], 2 * h[1], 2 * h[2]);
      break;
    }
    case 'cylinder':
      geom = new THREE.CylinderGeometry(g.radius, g.radius, g.length, 32);
      alongZ = true;
      break;
    case 'capsule':
      geom = new THREE.CapsuleGeometry(g.radius, g.length, 8, 24);
      alongZ = true;
      break;
    case 'sphere':
      geom = new THREE.SphereGeometry(g.radius, 24, 16);
      break;
    case 'mesh':
      mesh = meshShape(url, material, ctx, where);
      break;
    default:
      notes.push(`${where}: a ${g.type} shape is not drawn`);
      return null;
  }
  if (!mesh) mesh = new THREE.Mesh(geom, material);
  const local = poseMatrix(g.pose);
  if (alongZ) {
    // three.js cylinders and capsules run along y; manyhands' (like URDF's) along z.
    local.multiply(new THREE.Matrix4().makeRotationX(Math.PI / 2));
  }
  mesh.matrixAutoUpdate = false;
  mesh.matrix.copy(local);
  return mesh;
}

function bodyGroup(body, material, ctx, list, index) {
  const group = new THREE.Group();
  group.name = body.name;
  group.matrixAutoUpdate = false;
  group.matrix.copy(poseMatrix(body.pose));
  (body.shapes || []).forEach((g, i) => {
    const url = `/v1/scenes/${encodeURIComponent(ctx.sceneName)}/meshes/${list}/${index}/${i}`;
    const m = shapeMesh(g, material, ctx, `${list} ${body.name} shape ${i}`, url);
    if (m) group.add(m);
  });
  return group;
}

/**
 * Adds the scene's bodies to `root`; returns `{objects: Map(name → group), obstacles: [group], notes,
 * loaded}`. Objects (graspable) are drawn in a warm colour, obstacles in grey. Mesh shapes are
 * fetched with `fetchText(url)`; `loaded` resolves when they are drawn (or noted as not drawn).
 */
export function buildScene(scene, root, sceneName, fetchText) {
  const notes = [];
  const ctx = { notes, pending: [], sceneName, fetchText };
  const obstacleMat = new THREE.MeshStandardMaterial({ color: 0x9aa3ad, roughness: 0.9 });
  const objectMat = new THREE.MeshStandardMaterial({ color: 0xe0892b, roughness: 0.6 });
  const obstacles = [];
  for (const b of scene.obstacles || []) {
    // Own material per obstacle: the viewer fades the ones between the camera and the robots.
    const g = bodyGroup(b, obstacleMat.clone(), ctx, 'obstacles', obstacles.length);
    root.add(g);
    obstacles.push(g);
  }
  const objects = new Map();
  (scene.objects || []).forEach((b, i) => {
    const g = bodyGroup(b, objectMat, ctx, 'objects', i);
    root.add(g);
    objects.set(b.name, g);
  });
  return { objects, obstacles, notes, loaded: Promise.all(ctx.pending) };
}
