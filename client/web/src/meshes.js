// Mesh assembly: each MeshChunk's Draco bytes decoded by three.js's DRACOLoader (the decoder
// sculptd serves under /draco/) into one three.js mesh per chunk; a newer version replaces the
// chunk, empty bytes remove it. All chunks of an object share one quantisation frame, so the
// seams match exactly.
import * as THREE from 'three';
import { DRACOLoader } from 'three/examples/jsm/loaders/DRACOLoader.js';
import { num } from './connection.js';

export class ChunkMeshes {
  constructor(scene) {
    this.group = new THREE.Group();
    scene.add(this.group);
    this.loader = new DRACOLoader();
    this.loader.setDecoderPath('/draco/');
    this.chunks = new Map();  // key -> {mesh, version, faces, serverFaces}
    this.versions = new Map();  // key -> newest version asked for
    this.decodeMs = [];
    this.received = 0;
    this.decoding = 0;  // chunks handed to the decoder and not back yet
    this.lastChangeAt = 0;  // performance.now() when a chunk's mesh last came in
    this.material = new THREE.MeshStandardMaterial({ color: 0xc9a27e, roughness: 0.75, metalness: 0.0 });
    this.colouredMaterial = new THREE.MeshStandardMaterial({ vertexColors: true, roughness: 0.7 });
    this.onChange = () => {};
  }

  /** Handles one MeshChunk message. */
  add(chunk) {
    const key = `${chunk.object}/${chunk.key.join(',')}`;
    const version = num(chunk.version);
    this.received += 1;
    if ((this.versions.get(key) ?? -1) > version) return;  // an older mesh than one we have
    this.versions.set(key, version);
    if (!chunk.draco || chunk.draco.length === 0) {
      this.remove(key);
      this.onChange();
      return;
    }
    // The loader transfers the buffer it is given to its worker: hand it a copy.
    const bytes = chunk.draco.slice().buffer;
    const started = performance.now();
    this.decoding += 1;
    this.loader.parse(bytes, (geometry) => {
      this.decoding -= 1;
      this.decodeMs.push(performance.now() - started);
      if (this.versions.get(key) !== version) { geometry.dispose(); return; }
      const colour = geometry.getAttribute('color');
      if (colour) {
        let max = 0;
        for (let i = 0; i < colour.array.length; ++i) max = Math.max(max, colour.array[i]);
        if (max > 1) for (let i = 0; i < colour.array.length; ++i) colour.array[i] /= 255;
      }
      geometry.computeVertexNormals();
      geometry.computeBoundingBox();
      geometry.computeBoundingSphere();
      const mesh = new THREE.Mesh(geometry, colour ? this.colouredMaterial : this.material);
      mesh.userData.key = key;
      this.remove(key);
      this.group.add(mesh);
      const faces = geometry.index ? geometry.index.count / 3 : geometry.getAttribute('position').count / 3;
      this.chunks.set(key, { mesh, version, faces, serverFaces: chunk.faces });
      this.lastChangeAt = performance.now();
      this.onChange();
    }, (err) => {
      this.decoding -= 1;
      console.error(`chunk ${key}: Draco decode failed`, err);
    });
  }

  remove(key) {
    const c = this.chunks.get(key);
    if (!c) return;
    this.group.remove(c.mesh);
    c.mesh.geometry.dispose();
    this.chunks.delete(key);
  }

  /** Triangles drawn, and the totals the server declared for the same chunks. */
  totals() {
    let faces = 0, serverFaces = 0;
    for (const c of this.chunks.values()) { faces += c.faces; serverFaces += c.serverFaces; }
    return { chunks: this.chunks.size, faces, serverFaces };
  }

  /** The meshes' bounding box (world). */
  bounds() {
    const box = new THREE.Box3();
    for (const c of this.chunks.values()) box.union(c.mesh.geometry.boundingBox);
    return box;
  }

  meshes() { return [...this.chunks.values()].map((c) => c.mesh); }
}
