// The 3D view: the material laid down by time t (per robot a line buffer drawn up to the
// segments ended by t, the one under way up to the nozzle), travel, the chunks' outlines, the
// floor grid, each robot's outline and nozzle, a marker on the selected finding.
//
// Software GL draws about 15-20 M line segments a second, so a big plan is not redrawn whole
// each frame: the material, travel, grid and outlines are drawn into an off-screen target
// (colour and depth) and, while the camera and the filters stay, each frame only adds the
// segments ended since the last one; the target is copied to the screen with its depth and the
// moving parts (robots, the segments under way, the marker) are drawn over it, hidden where
// material is in front. A camera move, a filter or colour change, or going back in time redraws
// the target whole, a share a frame (while the camera moves, a coarse picture at half the
// resolution, from every k-th layer of a large plan).

import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
import { colourTable, TRAVEL_COLOUR } from './colours.js';

// While the camera moves, at most this many segments are drawn a frame (the rest when it rests).
const COARSE_SEGMENTS = 60_000;
const COARSE_MIN = 30_000;
// A frame adds at most this many segments to the target (about 0.1-0.2 s of software GL).
const FRAME_SEGMENTS = 200_000;
// The floor grid has at most about this many lines each way.
const MAX_GRID_LINES = 300;
// The floor grid's lines are drawn in at most about this many pieces.
const GRID_PIECES = 100_000;


// A box's 12 edges over the unit cube [0,1]^3, and its 6 faces (for a translucent fill).
function unitBoxEdges() {
  const c = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]];
  const e = [[0, 1], [1, 2], [2, 3], [3, 0], [4, 5], [5, 6], [6, 7], [7, 4], [0, 4], [1, 5], [2, 6], [3, 7]];
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.Float32BufferAttribute(e.flatMap(([a, b]) => [...c[a], ...c[b]]), 3));
  return g;
}

function unitBoxFaces() {
  const g = new THREE.BoxGeometry(1, 1, 1);
  g.translate(0.5, 0.5, 0.5);
  return g;
}

export function niceStep(raw) {
  const p = Math.pow(10, Math.floor(Math.log10(raw)));
  for (const m of [1, 2, 5, 10]) if (m * p >= raw) return m * p;
  return 10 * p;
}

export class View {
  constructor(container, meta, geo) {
    this.meta = meta;
    this.geo = geo;
    this.container = container;
    THREE.ColorManagement.enabled = false; // the colours as given (the palette's bytes on screen)
    const renderer = new THREE.WebGLRenderer({ antialias: false, preserveDrawingBuffer: true, stencil: true });
    renderer.outputColorSpace = THREE.LinearSRGBColorSpace;
    renderer.setPixelRatio(window.devicePixelRatio || 1);
    renderer.localClippingEnabled = true;
    renderer.autoClear = false;
    renderer.setClearColor(0xffffff, 1);
    container.appendChild(renderer.domElement);
    this.renderer = renderer;

    // the scene's box and the part's (the material, else everything)
    this.partBox = this.materialBox();
    const size = new THREE.Vector3(), centre = new THREE.Vector3();
    this.partBox.getSize(size);
    this.partBox.getCenter(centre);
    this.diag = Math.max(size.length(), 1);
    this.camera = new THREE.PerspectiveCamera(40, 1, this.diag / 2000, this.diag * 50);
    this.camera.up.set(0, 0, 1);
    this.controls = new OrbitControls(this.camera, renderer.domElement);
    this.controls.enableDamping = false;
    this.controls.screenSpacePanning = true;
    // the camera moves from the first change until 250 ms after the last (a wheel turn is many
    // small changes); meanwhile frames are coarse, then the whole picture is drawn again
    this.moving = false;
    this.controls.addEventListener('change', () => {
      if (this.placing) return; // the view buttons and the findings place the camera: no motion
      this.moving = true;
      clearTimeout(this.still);
      this.still = setTimeout(() => { this.moving = false; this.invalidate(); }, 250);
      this.invalidate();
    });

    this.accScene = new THREE.Scene(); // drawn into the target: grid, outlines
    this.liveScene = new THREE.Scene(); // drawn each frame over it
    this.clip = [new THREE.Plane(new THREE.Vector3(0, 0, 1), 1e9), new THREE.Plane(new THREE.Vector3(0, 0, -1), 1e9)];
    this.buildGrid();
    this.buildMaterial();
    this.buildOutlines();
    this.buildRobots();
    this.buildLive();
    this.buildComposite();
    this.showTravel = false; // as slicers show a preview: travel on demand
    this.colourMode = 'robot';
    this.acc = null; // what the target holds: {t, counts, tcounts} (material and travel drawn)
    this.onInvalidate = () => {};
    this.resize();
    this.resetView('reset');
  }

  // --- building ---------------------------------------------------------------------------
  materialBox() {
    const box = new THREE.Box3();
    const g = this.geo;
    const add = (pos) => {
      if (!pos.length) return;
      let lo = [65535, 65535, 65535], hi = [0, 0, 0];
      for (let i = 0; i < pos.length; i += 3) {
        for (let k = 0; k < 3; k++) {
          const v = pos[i + k];
          if (v < lo[k]) lo[k] = v;
          if (v > hi[k]) hi[k] = v;
        }
      }
      box.expandByPoint(new THREE.Vector3(g.world(lo[0], 0), g.world(lo[1], 1), g.world(lo[2], 2)));
      box.expandByPoint(new THREE.Vector3(g.world(hi[0], 0), g.world(hi[1], 1), g.world(hi[2], 2)));
    };
    for (const r of g.robots) add(r.material.pos);
    if (box.isEmpty()) for (const r of g.robots) add(r.travel.pos);
    if (box.isEmpty()) box.set(new THREE.Vector3(...g.lo), new THREE.Vector3(...g.hi));
    box.min.z = Math.min(box.min.z, 0);
    return box;
  }

  quantizedObject(obj) { // positions are uint16 over the scene's box
    obj.scale.set(this.geo.span[0], this.geo.span[1], this.geo.span[2]);
    obj.position.set(this.geo.lo[0], this.geo.lo[1], this.geo.lo[2]);
    obj.frustumCulled = false;
    obj.matrixAutoUpdate = false;
    obj.updateMatrix();
    return obj;
  }

  // The floor grid over the part and the robots' area (the scene's box and the robots' bodies
  // around it, with a margin), its step a round tenth of the part. Each line is made of pieces
  // a few steps long: software GL drops a whole line that reaches behind the camera, and a grid
  // metres wide around a small part always does (it showed only where the camera looked away
  // from the robots' area, or nothing).
  buildGrid() {
    const g = this.geo;
    const lo = new THREE.Vector3(...g.lo), hi = new THREE.Vector3(...g.hi);
    lo.min(this.partBox.min); hi.max(this.partBox.max);
    // the box holds the nozzles' paths and starts; a robot's body reaches this far around its nozzle
    let reach = 0;
    if (this.meta.placed) {
      for (const rec of this.meta.robots) {
        for (const box of Object.values(rec.outline || {})) {
          if (Array.isArray(box) && box.length === 4) reach = Math.max(reach, Math.hypot(Math.max(Math.abs(box[0]), Math.abs(box[1])), Math.max(Math.abs(box[2]), Math.abs(box[3]))));
        }
      }
    }
    lo.x -= reach; lo.y -= reach; hi.x += reach; hi.y += reach;
    const extent = Math.max(hi.x - lo.x, hi.y - lo.y, 1);
    const partExtent = Math.max(this.partBox.max.x - this.partBox.min.x, this.partBox.max.y - this.partBox.min.y, 1);
    // a round tenth of the part; coarser when that would take more than MAX_GRID_LINES lines (a
    // small part among robots a metre apart)
    const step = niceStep(Math.max(partExtent / 10, (extent * 1.3) / MAX_GRID_LINES));
    const n = Math.ceil((extent * 1.3) / step / 2) * 2;
    const cx = Math.round(((lo.x + hi.x) / 2) / step) * step, cy = Math.round(((lo.y + hi.y) / 2) / step) * step;
    const x0 = cx - (n / 2) * step, y0 = cy - (n / 2) * step;
    // steps a piece: one (longer pieces, even as long as the part's diagonal, were dropped too in
    // a G-code preview), more only past GRID_PIECES pieces
    const piece = Math.max(1, Math.ceil((2 * (n + 1) * n) / GRID_PIECES));
    const major = [], minor = [];
    for (let i = 0; i <= n; i++) {
      const out = (i === n / 2) ? major : minor; // the centre lines darker, as GridHelper draws them
      for (let j = 0; j < n; j += piece) {
        const a = j * step, b = Math.min(j + piece, n) * step, u = i * step;
        out.push(x0 + u, y0 + a, 0, x0 + u, y0 + b, 0, x0 + a, y0 + u, 0, x0 + b, y0 + u, 0);
      }
    }
    for (const [pos, colour] of [[minor, 0xdcdcdc], [major, 0xb0b0b0]]) {
      const geom = new THREE.BufferGeometry();
      geom.setAttribute('position', new THREE.Float32BufferAttribute(pos, 3));
      const lines = new THREE.LineSegments(geom, new THREE.LineBasicMaterial({ color: colour }));
      lines.frustumCulled = false;
      this.accScene.add(lines);
    }
    const axes = new THREE.AxesHelper(step);
    axes.position.set(x0, y0, 0);
    this.accScene.add(axes);
    this.gridStep = step;
    this.gridBox = [x0, y0, x0 + n * step, y0 + n * step]; // (the test hook's)
  }

  buildMaterial() {
    this.robots = this.geo.robots.map((r, i) => {
      const make = (paths, colour) => {
        const g = new THREE.BufferGeometry();
        g.setAttribute('position', new THREE.BufferAttribute(paths.segmentPositions(), 3, true));
        const mat = new THREE.LineBasicMaterial({ vertexColors: !!colour, color: colour ? 0xffffff : TRAVEL_COLOUR,
                                                  clippingPlanes: this.clip });
        if (colour) g.setAttribute('color', new THREE.BufferAttribute(new Uint8Array(paths.count * 6), 3, true));
        g.setDrawRange(0, 0);
        return this.quantizedObject(new THREE.LineSegments(g, mat));
      };
      const material = make(r.material, true);
      const travel = make(r.travel, false);
      return { data: r, index: i, material, travel, coarse: null };
    });
  }

  buildOutlines() {
    const pos = this.geo.outline;
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.BufferAttribute(pos, 3, true));
    const m = new THREE.LineBasicMaterial({ color: 0x303030, transparent: true, opacity: 0.55, clippingPlanes: this.clip });
    this.outlines = this.quantizedObject(new THREE.LineSegments(g, m));
    this.outlines.visible = false;
    this.accScene.add(this.outlines);
  }

  buildRobots() {
    const edges = unitBoxEdges(), faces = unitBoxFaces();
    const r = Math.max(this.diag / 250, 0.5);
    this.nozzleSize = r;
    this.robotViews = this.meta.robots.map((rec, i) => {
      const colour = new THREE.Color(...rec.colour.map((c) => c / 255));
      const group = new THREE.Group();
      const line = new THREE.LineBasicMaterial({ color: colour });
      const part = (geom, material) => { const o = new THREE.LineSegments(geom, material); group.add(o); return o; };
      const view = { group, rec, colour };
      if (this.meta.placed && rec.outline) {
        view.body = part(edges, line);
        view.bodyFill = new THREE.Mesh(faces, new THREE.MeshBasicMaterial({ color: colour, transparent: true,
                                                                            opacity: 0.1, depthWrite: false }));
        group.add(view.bodyFill);
        view.column = part(edges, line);
        view.frame = part(edges, line);
        view.head = part(edges, line);
        view.mast = part(new THREE.BufferGeometry().setAttribute('position',
          new THREE.Float32BufferAttribute([0, 0, 0, 0, 0, 1], 3)), line);
      }
      const nozzle = new THREE.Mesh(new THREE.ConeGeometry(r, 2.5 * r, 16).rotateX(-Math.PI / 2).translate(0, 0, 1.25 * r),
                                    new THREE.MeshBasicMaterial({ color: colour }));
      const ring = new THREE.LineSegments(new THREE.EdgesGeometry(nozzle.geometry),
                                         new THREE.LineBasicMaterial({ color: 0x202020 }));
      nozzle.add(ring);
      group.add(nozzle);
      view.nozzle = nozzle;
      this.liveScene.add(group);
      return view;
    });
    // the selected finding
    const m = new THREE.Mesh(new THREE.SphereGeometry(r * 1.6, 16, 12),
                             new THREE.MeshBasicMaterial({ color: 0xe00000, transparent: true, opacity: 0.6, depthTest: false }));
    const ring = new THREE.Mesh(new THREE.TorusGeometry(r * 4, r * 0.4, 8, 32),
                                new THREE.MeshBasicMaterial({ color: 0xe00000, depthTest: false }));
    m.add(ring);
    m.visible = false;
    m.renderOrder = 10;
    ring.renderOrder = 10;
    this.marker = m;
    this.liveScene.add(m);
  }

  buildLive() { // the segments under way: one material and one travel segment per robot
    const n = this.geo.robots.length * 2;
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.BufferAttribute(new Float32Array(n * 6), 3));
    g.setAttribute('color', new THREE.BufferAttribute(new Float32Array(n * 6), 3));
    g.setDrawRange(0, 0);
    this.live = new THREE.LineSegments(g, new THREE.LineBasicMaterial({ vertexColors: true, clippingPlanes: this.clip }));
    this.live.frustumCulled = false;
    this.liveScene.add(this.live);
  }

  buildComposite() { // the target that keeps the material (and, where needed, the frame's)
    this.target = null;
    this.frameTarget = null;
    this.direct = undefined; // whether the target's depth can be copied to the canvas's (tried once)
  }

  // Copy a target's colour, depth and stencil to another, or to the canvas (null): a blit of the
  // rectangle [x0, y0, x1, y1] (pixels from the bottom left; all by default). Returns whether it
  // worked (a canvas whose depth format differs from the target's refuses it).
  blit(src, dst, depth, rect = null, scaled = false) {
    const gl = this.renderer.getContext(), props = this.renderer.properties;
    const fb = (t) => (t ? props.get(t).__webglFramebuffer : null);
    const [x0, y0, x1, y1] = rect || [0, 0, src.width, src.height];
    const [w, h] = scaled ? [this.target.width, this.target.height] : [x1, y1]; // a coarse frame: stretched
    const check = this.direct === undefined; // asking for errors waits for the GPU: only the first time
    if (check) gl.getError();
    gl.bindFramebuffer(gl.READ_FRAMEBUFFER, fb(src));
    gl.bindFramebuffer(gl.DRAW_FRAMEBUFFER, fb(dst));
    gl.blitFramebuffer(x0, y0, x1, y1, scaled ? 0 : x0, scaled ? 0 : y0, w, h,
                       gl.COLOR_BUFFER_BIT | (depth ? gl.DEPTH_BUFFER_BIT : 0), gl.NEAREST);
    const ok = !check || gl.getError() === gl.NO_ERROR;
    this.renderer.resetState();
    return ok;
  }

  // The frame on the canvas: the target's picture and depth, the moving parts drawn over it.
  // The canvas keeps its picture between frames, so after a frame that only added material the
  // copy covers just where the moving parts were (their old places restored from the target),
  // the new material is drawn onto the canvas too, then the moving parts where they are now.
  // A canvas that cannot take the target's depth goes through a second target (two copies).
  present(t, counts, full, added, source = this.target) {
    const renderer = this.renderer;
    const scaled = source !== this.target;
    this.updateLive(t, counts);
    if (this.direct !== false) {
      renderer.setRenderTarget(null);
      const whole = full || !this.liveRect || scaled;
      const ok = this.blit(source, null, true, whole ? null : this.liveRect, scaled);
      if (this.direct === undefined) this.direct = ok;
      if (ok) {
        if (!whole && added && added.children.length) renderer.render(added, this.camera);
        renderer.render(this.liveScene, this.camera);
        this.liveRect = scaled ? null : this.screenRect();
        return;
      }
    }
    if (!this.frameTarget) this.frameTarget = this.makeTarget();
    this.blit(source, this.frameTarget, true, null, scaled);
    renderer.setRenderTarget(this.frameTarget);
    renderer.render(this.liveScene, this.camera);
    renderer.setRenderTarget(null);
    this.blit(this.frameTarget, null, false);
  }

  // The pixels the moving parts cover (robots, the segments under way, the marker), with a
  // margin; null (all) when a part is behind the camera.
  screenRect() {
    const w = this.target.width, h = this.target.height;
    const box = new THREE.Box3(), p = new THREE.Vector3();
    let x0 = Infinity, y0 = Infinity, x1 = -Infinity, y1 = -Infinity;
    const parts = [...this.robotViews.map((v) => v.group), this.live, ...(this.marker.visible ? [this.marker] : [])];
    this.live.geometry.computeBoundingBox();
    for (const o of parts) {
      o.updateMatrixWorld(true);
      if (o === this.live) { if (this.live.geometry.drawRange.count === 0) continue; box.copy(o.geometry.boundingBox); }
      else box.setFromObject(o);
      if (box.isEmpty()) continue;
      for (let c = 0; c < 8; c++) {
        p.set(c & 1 ? box.max.x : box.min.x, c & 2 ? box.max.y : box.min.y, c & 4 ? box.max.z : box.min.z);
        p.applyMatrix4(this.camera.matrixWorldInverse);
        if (p.z > -this.camera.near) return null; // behind the camera: all
        p.applyMatrix4(this.camera.projectionMatrix);
        const x = ((p.x + 1) / 2) * w, y = ((p.y + 1) / 2) * h;
        x0 = Math.min(x0, x); x1 = Math.max(x1, x); y0 = Math.min(y0, y); y1 = Math.max(y1, y);
      }
    }
    if (x0 > x1) return [0, 0, 0, 0];
    const m = 3;
    return [Math.max(0, Math.floor(x0) - m), Math.max(0, Math.floor(y0) - m), Math.min(w, Math.ceil(x1) + m),
            Math.min(h, Math.ceil(y1) + m)];
  }

  makeTarget(divisor = 1) {
    const px = new THREE.Vector2();
    this.renderer.getDrawingBufferSize(px);
    const t = new THREE.WebGLRenderTarget(Math.ceil(px.x / divisor), Math.ceil(px.y / divisor), { depthBuffer: true, stencilBuffer: true,
                                                        minFilter: THREE.NearestFilter, magFilter: THREE.NearestFilter });
    this.renderer.setRenderTarget(t); // made now: its framebuffer exists for the blits
    this.renderer.setRenderTarget(null);
    return t;
  }

  // --- state ------------------------------------------------------------------------------
  invalidate() { this.acc = null; this.onInvalidate(); }

  resize() {
    const w = Math.max(this.container.clientWidth, 16), h = Math.max(this.container.clientHeight, 16);
    this.renderer.setSize(w, h);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    for (const t of [this.target, this.frameTarget, this.coarseTarget]) if (t) t.dispose();
    this.target = this.makeTarget();
    this.frameTarget = null;
    this.coarseTarget = null;
    this.liveRect = null; // the canvas is cleared: copied whole next
    this.invalidate();
  }

  // Lines have no surface to light: each segment is shaded by how its horizontal normal (across
  // it) faces a light from the front right, so that walls read as lit from one side; most keep
  // their full colour (the palette's exact colour on screen), the others are darker, down to 55 %.
  shading(m) {
    if (m.shade) return m.shade;
    const out = new Float32Array(m.count), span = this.geo.span, L = [0.8, -0.6];
    for (let s = 0; s < m.count; s++) {
      const a = m.start[s] * 3;
      const dx = (m.pos[a + 3] - m.pos[a]) * span[0], dy = (m.pos[a + 4] - m.pos[a + 1]) * span[1];
      const len = Math.hypot(dx, dy);
      out[s] = len > 0 ? Math.min(1, 0.55 + 0.7 * Math.abs(-dy * L[0] + dx * L[1]) / len) : 1;
    }
    m.shade = out;
    return out;
  }

  setColours(mode, colours) {
    this.colourMode = mode;
    for (const r of this.robots) {
      const attr = r.material.geometry.getAttribute('color');
      const out = attr.array;
      const table = colourTable(mode, r.index, r.data.material, colours);
      const per = table.per;
      const shade = this.shading(r.data.material);
      for (let s = 0; s < r.data.material.count; s++) {
        const c = per(s), o = s * 6, f = shade[s];
        out[o] = out[o + 3] = Math.round(c[0] * f);
        out[o + 1] = out[o + 4] = Math.round(c[1] * f);
        out[o + 2] = out[o + 5] = Math.round(c[2] * f);
      }
      attr.needsUpdate = true;
      r.coarse = null;
    }
    this.invalidate();
  }

  setTravel(on) { this.showTravel = on; this.invalidate(); }
  setOutlines(on) { this.outlines.visible = on; this.invalidate(); }
  setLayers(lo, hi) {
    this.clip[0].constant = -lo + 1e-6;
    this.clip[1].constant = hi + 1e-6;
    this.invalidate();
  }

  resetView(which) {
    const box = this.partBox;
    const c = new THREE.Vector3(), s = new THREE.Vector3();
    box.getCenter(c); box.getSize(s);
    const r = Math.max(s.length() / 2, 1);
    const d = r / Math.sin(THREE.MathUtils.degToRad(this.camera.fov / 2)) * 1.05;
    const dirs = {
      reset: new THREE.Vector3(Math.sin(THREE.MathUtils.degToRad(-35)) * Math.cos(THREE.MathUtils.degToRad(30)),
                               -Math.cos(THREE.MathUtils.degToRad(-35)) * Math.cos(THREE.MathUtils.degToRad(30)),
                               Math.sin(THREE.MathUtils.degToRad(30))),
      top: new THREE.Vector3(0, -1e-3, 1), front: new THREE.Vector3(0, -1, 0), side: new THREE.Vector3(1, 0, 0),
    };
    const dir = dirs[which].normalize();
    this.controls.target.copy(c);
    this.camera.position.copy(c).addScaledVector(dir, d);
    this.camera.lookAt(c);
    this.place();
  }

  lookAt(point) { // keep the camera's direction and distance, centred on point
    const offset = this.camera.position.clone().sub(this.controls.target);
    const close = Math.min(offset.length(), this.diag * 0.6);
    offset.setLength(close);
    this.controls.target.set(...point);
    this.camera.position.copy(this.controls.target).add(offset);
    this.place();
  }

  place() { // the camera set from code: one full frame, not a motion
    this.placing = true;
    this.controls.update();
    this.placing = false;
    this.invalidate();
  }

  showMarker(point) {
    if (!point) { this.marker.visible = false; return; }
    this.marker.position.set(...point);
    this.marker.visible = true;
  }

  // --- drawing ----------------------------------------------------------------------------
  // While the camera moves, a plan of more than COARSE_MIN segments is drawn at half the
  // resolution (a quarter of the pixels: long lines cost by their pixels) and, above
  // COARSE_SEGMENTS, from every k-th layer (its heights ranked): the part keeps its shape, a
  // frame takes a fraction of a full one. Returns k (0: no coarse frames).
  coarseLayers() {
    if (this.coarseK !== undefined) return this.coarseK;
    const total = this.robots.reduce((a, x) => a + x.data.material.count, 0);
    this.coarseK = total > COARSE_MIN ? 1 : 0;
    if (total <= COARSE_SEGMENTS) return this.coarseK;
    const perZ = new Float64Array(65536);
    for (const r of this.robots) {
      const m = r.data.material;
      for (let s = 0; s < m.count; s++) perZ[m.pos[m.start[s] * 3 + 2]]++;
    }
    const rank = new Int32Array(65536).fill(-1);
    const levels = [];
    for (let z = 0; z < 65536; z++) if (perZ[z]) { rank[z] = levels.length; levels.push(perZ[z]); }
    let k = Math.max(2, Math.floor(total / COARSE_SEGMENTS));
    const kept = (k) => levels.reduce((a, n, i) => a + (i % k === 0 ? n : 0), 0);
    while (kept(k) > COARSE_SEGMENTS) k++;
    this.coarseK = k;
    this.zRank = rank;
    return k;
  }

  coarseOf(r) {
    const k = this.coarseLayers();
    if (k === 1) return { below: (c) => c, object: r.material };
    if (!r.coarse) {
      const m = r.data.material, rank = this.zRank;
      let n = 0;
      for (let s = 0; s < m.count; s++) if (rank[m.pos[m.start[s] * 3 + 2]] % k === 0) n++;
      const orig = new Uint32Array(n), pos = new Uint16Array(n * 6), col = new Uint8Array(n * 6);
      const sp = r.material.geometry.getAttribute('position').array, sc = r.material.geometry.getAttribute('color').array;
      let j = 0;
      for (let s = 0; s < m.count; s++) {
        if (rank[m.pos[m.start[s] * 3 + 2]] % k !== 0) continue;
        orig[j] = s;
        pos.set(sp.subarray(s * 6, s * 6 + 6), j * 6);
        col.set(sc.subarray(s * 6, s * 6 + 6), j * 6);
        j++;
      }
      const g = new THREE.BufferGeometry();
      g.setAttribute('position', new THREE.BufferAttribute(pos, 3, true));
      g.setAttribute('color', new THREE.BufferAttribute(col, 3, true));
      const below = (c) => { // coarse segments of the first c
        let lo = 0, hi = n;
        while (lo < hi) { const mid = (lo + hi) >>> 1; if (orig[mid] < c) lo = mid + 1; else hi = mid; }
        return lo;
      };
      r.coarse = { below, object: this.quantizedObject(new THREE.LineSegments(g, r.material.material)) };
    }
    return r.coarse;
  }

  // A frame while the camera moves: the material up to t from the coarse subset, at half the
  // resolution, stretched onto the canvas; the target is drawn again once the camera rests.
  renderCoarse(t, want) {
    const renderer = this.renderer;
    if (!this.coarseTarget) this.coarseTarget = this.makeTarget(2);
    renderer.setRenderTarget(this.coarseTarget);
    renderer.clear(true, true, true);
    renderer.render(this.accScene, this.camera);
    const scene = new THREE.Scene();
    const used = [];
    this.robots.forEach((r, i) => {
      const c = this.coarseOf(r), b = c.below(want[i]);
      if (b > 0) { c.object.geometry.setDrawRange(0, b * 2); scene.add(c.object); used.push(c.object); }
    });
    if (scene.children.length) renderer.render(scene, this.camera);
    used.forEach((o) => o.removeFromParent());
    this.acc = null;
    this.present(t, want, true, null, this.coarseTarget);
  }

  // Draw the frame at time t. The target catches up with t by at most FRAME_SEGMENTS segments a
  // frame (the material up to an earlier time t' first: the print grows to t over a few frames,
  // and the page answers meanwhile); returns whether it has (else the caller draws again).
  render(t) {
    const renderer = this.renderer;
    const want = this.robots.map((r) => r.data.material.ended(t));
    if (this.moving && this.coarseLayers()) {
      this.renderCoarse(t, want);
      return true;
    }
    const full = !this.acc || want.some((c, i) => c < this.acc.counts[i])
      || this.robots.some((r, i) => this.showTravel && r.data.travel.ended(t) < this.acc.tcounts[i])
      || (!this.showTravel && this.acc.tcounts.some((c) => c > 0));
    renderer.setRenderTarget(this.target);
    if (full) {
      renderer.clear(true, true, true);
      renderer.render(this.accScene, this.camera);
      this.acc = { t: 0, counts: this.robots.map(() => 0), tcounts: this.robots.map(() => 0) };
    }
    const acc = this.acc;
    const have = acc.counts.reduce((a, b) => a + b, 0);
    const ended = (x) => this.robots.reduce((a, r) => a + r.data.material.ended(x), 0);
    let upTo = t;
    if (ended(t) - have > FRAME_SEGMENTS) { // the latest time within the frame's share
      let lo = acc.t, hi = t;
      for (let k = 0; k < 60 && hi - lo > 1e-9 * Math.max(t, 1); k++) {
        const mid = (lo + hi) / 2;
        if (ended(mid) - have > FRAME_SEGMENTS) hi = mid; else lo = mid;
      }
      upTo = lo;
    }
    const counts = this.robots.map((r) => r.data.material.ended(upTo));
    const tcounts = this.robots.map((r) => (this.showTravel ? r.data.travel.ended(upTo) : 0));
    const added = new THREE.Scene();
    let drawn = 0;
    this.robots.forEach((r, i) => {
      const from = acc.counts[i], to = counts[i];
      if (to > from) {
        r.material.geometry.setDrawRange(from * 2, (to - from) * 2);
        added.add(r.material);
        drawn += to - from;
      }
      const tf = acc.tcounts[i], tt = tcounts[i];
      if (tt > tf) {
        r.travel.geometry.setDrawRange(tf * 2, (tt - tf) * 2);
        added.add(r.travel);
        drawn += tt - tf;
      }
    });
    if (added.children.length) renderer.render(added, this.camera);
    this.acc = { t: upTo, counts, tcounts };
    // a little new material is drawn onto the canvas too; much of it, the canvas is copied whole
    this.present(t, want, full || drawn > FRAME_SEGMENTS / 10, added);
    for (const r of this.robots) { r.material.removeFromParent(); r.travel.removeFromParent(); } // (one parent each)
    return upTo >= t;
  }

  updateLive(t, counts) {
    const pos = this.live.geometry.getAttribute('position'), col = this.live.geometry.getAttribute('color');
    const g = this.geo;
    let n = 0;
    const put = (p, q, c) => {
      pos.array.set([...p, ...q], n * 6);
      col.array.set([...c, ...c], n * 6);
      n++;
    };
    this.robots.forEach((r, i) => {
      const m = r.data.material;
      const s = counts[i];
      if (s < m.count && m.t0(s) < t) {
        const a = m.start[s] * 3, f = (t - m.t0(s)) / Math.max(m.t1(s) - m.t0(s), 1e-12);
        const p = [0, 1, 2].map((k) => g.world(m.pos[a + k], k));
        const q = [0, 1, 2].map((k) => g.world(m.pos[a + k] + f * (m.pos[a + 3 + k] - m.pos[a + k]), k));
        const c = r.material.geometry.getAttribute('color').array;
        put(p, q, [c[s * 6] / 255, c[s * 6 + 1] / 255, c[s * 6 + 2] / 255]);
      }
      const tr = r.data.travel;
      const k = tr.ended(t);
      if (this.showTravel && k < tr.count && tr.t0(k) < t) {
        const a = tr.start[k] * 3, f = (t - tr.t0(k)) / Math.max(tr.t1(k) - tr.t0(k), 1e-12);
        const p = [0, 1, 2].map((j) => g.world(tr.pos[a + j], j));
        const q = [0, 1, 2].map((j) => g.world(tr.pos[a + j] + f * (tr.pos[a + 3 + j] - tr.pos[a + j]), j));
        put(p, q, [TRAVEL_COLOUR_RGB[0] / 255, TRAVEL_COLOUR_RGB[1] / 255, TRAVEL_COLOUR_RGB[2] / 255]);
      }
    });
    pos.needsUpdate = true; col.needsUpdate = true;
    this.live.geometry.setDrawRange(0, n * 2);
  }

  // Each robot's outline where it is at t (position: its nozzle, mm; facing: degrees).
  placeRobots(poses) {
    poses.forEach((pose, i) => {
      const v = this.robotViews[i];
      const [x, y, z] = pose.position;
      v.group.position.set(x, y, 0);
      v.group.rotation.set(0, 0, THREE.MathUtils.degToRad(pose.facing));
      v.nozzle.position.set(0, 0, z);
      if (v.body) {
        const o = v.rec.outline, zh = z + v.rec.nozzle_height;
        const box = (obj, [u0, u1, v0, v1], z0, z1) => {
          obj.position.set(u0, v0, z0);
          obj.scale.set(Math.max(u1 - u0, 1e-3), Math.max(v1 - v0, 1e-3), Math.max(z1 - z0, 1e-3));
        };
        const hb = Math.min(zh, 0.35 * (o.body[3] - o.body[2])); // the body: a low box on its wheels
        box(v.body, o.body, 0, hb);
        box(v.bodyFill, o.body, 0, hb);
        box(v.column, [o.body[1] - 1, o.body[1], o.frame[2], o.frame[3]], hb, zh); // up to the frame
        box(v.frame, o.frame, zh, zh + v.rec.nozzle_height * 0.08);
        box(v.head, o.printhead, zh, zh + v.rec.nozzle_height * 0.5);
        v.mast.position.set(0, 0, z);
        v.mast.scale.set(1, 1, Math.max(zh - z, 1e-3));
      }
    });
  }
}

const TRAVEL_COLOUR_RGB = [(TRAVEL_COLOUR >> 16) & 255, (TRAVEL_COLOUR >> 8) & 255, TRAVEL_COLOUR & 255];
