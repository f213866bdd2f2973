// cooprint's plan viewer (placeholder until the viewer lands): see docs/viewer.md.
import * as THREE from 'three';

window.cooprintThreeRevision = THREE.REVISION;
