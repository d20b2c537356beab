// A robot's visual geometry (its URDF's `<visual>` elements) from `GET /v1/robots/{name}/visuals`:
// boxes, cylinders, capsules, spheres and meshes (fetched as OBJ text from the server, which
// reads only the files the robot's model names), added to the links of a robot built by
// urdf-loader from its collision model. Each link shows its visual geometry when it has some
// that loaded, else its collision geometry; `setGeometryMode('collision')` shows the collision
// geometry of every link.
import * as THREE from 'three';
import { OBJLoader } from 'three/examples/jsm/loaders/OBJLoader.js';
import { poseMatrix } from './scene.js';

/** Parsed OBJ meshes by URL, shared by every robot of one model (cloned, geometry shared). */
const meshCache = new Map();

/** Mesh fetches in flight at most (the server reads mesh files on its bounded heavy lane). */
const MAX_FETCHES = 2;
let inFlight = 0;
const waiting = [];
async function throttled(f) {
  // A finished fetch hands its slot to the next waiting one.
  if (inFlight >= MAX_FETCHES) await new Promise((r) => waiting.push(r));
  else inFlight += 1;
  try {
    return await f();
  } finally {
    const next = waiting.shift();
    if (next) next();
    else inFlight -= 1;
  }
}

function loadObj(url, fetchText) {
  if (!meshCache.has(url)) {
    meshCache.set(
      url,
      throttled(() => fetchText(url)).then((text) => {
        const parsed = new OBJLoader().parse(text);
        let triangles = 0;
        parsed.traverse((o) => {
          if (!o.isMesh) return;
          if (!o.geometry.getAttribute('normal')) o.geometry.computeVertexNormals();
          triangles += o.geometry.getAttribute('position').count / 3;
        });
        if (!triangles) throw new Error('the mesh has no triangles');
        return parsed;
      }),
    );
  }
  return meshCache.get(url).then((o) => o.clone());
}

/** three.js object of one visual's shape JSON (null for what is not drawn), or a promise of it for meshes. */
function shapeObject(shape, material, fetchText) {
  let geom;
  let alongZ = false;
  switch (shape.type) {
    case 'box': {
      const h = shape.half_extents;
      geom = new THREE.BoxGeometry(2 * h[0], 2 * h[1], 2 * h[2]);
      break;
    }
    case 'cylinder':
      geom = new THREE.CylinderGeometry(shape.radius, shape.radius, shape.length, 32);
      alongZ = true;
      break;
    case 'capsule':
      geom = new THREE.CapsuleGeometry(shape.radius, shape.length, 8, 24);
      alongZ = true;
      break;
    case 'sphere':
      geom = new THREE.SphereGeometry(shape.radius, 24, 16);
      break;
    case 'mesh':
      return loadObj(shape.url, fetchText).then((o) => {
        o.traverse((m) => {
          if (m.isMesh) m.material = material;
        });
        return o;
      });
    default:
      return Promise.reject(new Error(`a ${shape.type} visual is not drawn`));
  }
  const mesh = new THREE.Mesh(geom, material);
  if (alongZ) {
    // three.js cylinders and capsules run along y; URDF's along z.
    mesh.rotation.x = Math.PI / 2;
  }
  return Promise.resolve(mesh);
}

/**
 * Adds the visual geometry listed in `visuals` (the endpoint's answer, `null` when the robot has
 * none) to `robot` (urdf-loader's object) in `material`. Resolves to
 * `{links: Map(link → visual group), drawn, failed: [reason]}` when every element is drawn or
 * has failed; a link with a failed element keeps showing its collision geometry.
 */
export async function addVisuals(robot, visuals, material, fetchText) {
  const groups = new Map();
  const failedLinks = new Set();
  const failed = [];
  let drawn = 0;
  const jobs = [];
  for (const v of (visuals && visuals.visuals) || []) {
    const link = robot.links[v.link];
    if (!link) {
      failed.push(`${v.link}: no such link`);
      continue;
    }
    if (!v.shape || v.problem) {
      failedLinks.add(v.link);
      failed.push(`${v.link}: ${v.problem || 'nothing to draw'}`);
      continue;
    }
    if (!groups.has(v.link)) {
      const g = new THREE.Group();
      g.name = `visual:${v.link}`;
      g.userData.isVisualGeometry = true;
      link.add(g);
      groups.set(v.link, g);
    }
    const group = groups.get(v.link);
    jobs.push(
      shapeObject(v.shape, material, fetchText).then(
        (obj) => {
          const holder = new THREE.Group();
          holder.matrixAutoUpdate = false;
          holder.matrix.copy(poseMatrix(v.pose));
          holder.add(obj);
          group.add(holder);
          drawn += 1;
        },
        (e) => {
          failedLinks.add(v.link);
          failed.push(`${v.link}: ${e.message || e}`);
        },
      ),
    );
  }
  await Promise.all(jobs);
  for (const l of failedLinks) {
    const g = groups.get(l);
    if (g) g.removeFromParent();
    groups.delete(l);
  }
  return { links: groups, drawn, failed };
}

/**
 * Shows, on every link of `robot`, its visual geometry (`mode` 'visual', for links whose visual
 * geometry loaded) or its collision geometry (`mode` 'collision', and links without visuals).
 */
export function setGeometryMode(robot, visualLinks, mode) {
  for (const [name, link] of Object.entries(robot.links)) {
    const visual = mode === 'visual' && visualLinks.has(name);
    for (const c of link.children) {
      if (c.isURDFCollider) c.visible = !visual;
      else if (c.userData.isVisualGeometry) c.visible = visual;
    }
  }
}
