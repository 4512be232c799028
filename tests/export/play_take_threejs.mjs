// Plays an animated .glb in three.js (the web's glTF engine) inside Debian's chromium and prints
// what the engine evaluates at the given times: the mesh's 52 morph target influences and the
// head node's world position and rotation. No WebGL is needed: the loader and the animation
// mixer run on the page's JavaScript. playwright-core and three are installed into NPM_DIR on
// the first run (as the kiosk's browser tests install playwright-core).
//   node play_take_threejs.mjs NPM_DIR FILE.glb T1,T2,...
// Exit 77 (skip) without /usr/bin/chromium; prints JSON {three, names, at: [{t, weights,
// position, quaternion}]}.
import {execFileSync} from "node:child_process";
import fs from "node:fs";
import path from "node:path";
import {createRequire} from "node:module";

const [npmDir, glbFile] = process.argv.slice(2, 4).map((p) => path.resolve(p));
const times = process.argv[4].split(",").map(Number);
const CHROMIUM = "/usr/bin/chromium";
if (!fs.existsSync(CHROMIUM)) {
  console.error("SKIP: /usr/bin/chromium is not installed (apt-get install chromium)");
  process.exit(77);
}
const modules = path.join(npmDir, "node_modules");
if (!fs.existsSync(path.join(modules, "playwright-core")) ||
    !fs.existsSync(path.join(modules, "three"))) {
  fs.mkdirSync(npmDir, {recursive: true});
  console.error("installing playwright-core and three into", npmDir);
  execFileSync("npm", ["install", "--no-audit", "--no-fund", "--prefix", npmDir,
                       "playwright-core@1", "three@0.160.0"], {stdio: ["ignore", 2, 2]});
}
const require = createRequire(path.join(npmDir, "package.json"));
const {chromium} = require("playwright-core");

// The page, three.js and the file are served from disk under one made-up origin (module
// imports are not allowed from file:// URLs).
const ORIGIN = "http://facebooth.test";
const page_html = `<!doctype html><html><head><script type="importmap">
{"imports": {"three": "${ORIGIN}/three/build/three.module.js"}}</script></head><body>
<script type="module">
import * as THREE from "three";
import {GLTFLoader} from "${ORIGIN}/three/examples/jsm/loaders/GLTFLoader.js";
window.play = (times) => new Promise((resolve, reject) => {
  new GLTFLoader().load("${ORIGIN}/take.glb", (gltf) => {
    const mixer = new THREE.AnimationMixer(gltf.scene);
    mixer.clipAction(gltf.animations[0]).play();
    let mesh = null;
    gltf.scene.traverse((o) => { if (o.isMesh) mesh = o; });
    const head = gltf.scene.getObjectByName("head");
    const names = Object.entries(mesh.morphTargetDictionary).sort((a, b) => a[1] - b[1])
                      .map((e) => e[0]);
    const at = times.map((t) => {
      mixer.setTime(t);
      gltf.scene.updateMatrixWorld(true);
      const p = new THREE.Vector3(), q = new THREE.Quaternion(), s = new THREE.Vector3();
      head.matrixWorld.decompose(p, q, s);
      return {t, weights: Array.from(mesh.morphTargetInfluences), position: p.toArray(),
              quaternion: q.toArray()};
    });
    resolve({three: THREE.REVISION, duration: gltf.animations[0].duration, names, at});
  }, undefined, (e) => reject(String(e)));
});
</script></body></html>`;

const types = {".js": "text/javascript", ".glb": "model/gltf-binary"};
const browser = await chromium.launch({executablePath: CHROMIUM, args: ["--no-sandbox"]});
try {
  const page = await browser.newPage();
  await page.route(`${ORIGIN}/**`, (route) => {
    const url = new URL(route.request().url());
    if (url.pathname === "/index.html")
      return route.fulfill({contentType: "text/html", body: page_html});
    const file = url.pathname === "/take.glb" ? glbFile
        : url.pathname.startsWith("/three/")
        ? path.join(modules, "three", url.pathname.slice("/three/".length)) : null;
    if (file === null || !fs.existsSync(file)) return route.fulfill({status: 404, body: ""});
    return route.fulfill({contentType: types[path.extname(file)] || "application/octet-stream",
                          body: fs.readFileSync(file)});
  });
  await page.goto(`${ORIGIN}/index.html`);
  await page.waitForFunction(() => typeof window.play === "function");
  console.log(JSON.stringify(await page.evaluate((t) => window.play(t), times)));
} finally {
  await browser.close();
}
