// The scene's obstacles and objects as three.js meshes (z up, metres), from the scene JSON of
// `GET /v1/scenes/{name}`: bodies with a pose and shapes (box, cylinder, sphere, capsule, mesh).
import * as THREE from 'three';

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

/** Mesh of one shape JSON, or null (with the reason pushed to `notes`) for what is not drawn. */
function shapeMesh(g, material, notes, where) {
  let geom;
  let alongZ = false;
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
    default:
      notes.push(`${where}: a ${g.type} shape is not drawn`);
      return null;
  }
  const mesh = new THREE.Mesh(geom, material);
  const local = poseMatrix(g.pose);
  if (alongZ) {
    // three.js cylinders and capsules run along y; manyhands' (like URDF's) along z.
    local.multiply(new THREE.Matrix4().makeRotationX(Math.PI / 2));
  }
  mesh.matrixAutoUpdate = false;
  mesh.matrix.copy(local);
  return mesh;
}

function bodyGroup(body, material, notes, kind) {
  const group = new THREE.Group();
  group.name = body.name;
  group.matrixAutoUpdate = false;
  group.matrix.copy(poseMatrix(body.pose));
  (body.shapes || []).forEach((g, i) => {
    const m = shapeMesh(g, material, notes, `${kind} ${body.name} shape ${i}`);
    if (m) group.add(m);
  });
  return group;
}

/**
 * Adds the scene's bodies to `root`; returns `{objects: Map(name → group), obstacles: [group], notes}`. Objects
 * (graspable) are drawn in a warm colour, obstacles in grey.
 */
export function buildScene(scene, root) {
  const notes = [];
  const obstacleMat = new THREE.MeshStandardMaterial({ color: 0x9aa3ad, roughness: 0.9 });
  const objectMat = new THREE.MeshStandardMaterial({ color: 0xe0892b, roughness: 0.6 });
  const obstacles = [];
  for (const b of scene.obstacles || []) {
    // Own material per obstacle: the viewer fades the ones between the camera and the robots.
    const g = bodyGroup(b, obstacleMat.clone(), notes, 'obstacle');
    root.add(g);
    obstacles.push(g);
  }
  const objects = new Map();
  for (const b of scene.objects || []) {
    const g = bodyGroup(b, objectMat, notes, 'object');
    root.add(g);
    objects.set(b.name, g);
  }
  return { objects, obstacles, notes };
}
