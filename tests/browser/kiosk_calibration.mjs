// The kiosk page on a camera that needs calibration: faceboothd on a decalibrated synthetic
// unit (registration 14 px off, reporting the defaults like a Kinect without a device.json).
// The page must show "Camera needs calibration" plainly with what to do; its "Calibrate camera"
// button self-calibrates and the warning goes away. Saves screenshots into the build directory.
//   node kiosk_calibration.mjs FACEBOOTHD OUT_DIR GUIDE_JSON
import {spawn, execFileSync} from "node:child_process";
import fs from "node:fs";
import path from "node:path";
import {createRequire} from "node:module";

const [daemonBin, outDir, guideFile] = process.argv.slice(2).map((p) => path.resolve(p));
const CHROMIUM = "/usr/bin/chromium";
if (!fs.existsSync(CHROMIUM)) {
  console.log("SKIP: /usr/bin/chromium is not installed (apt-get install chromium)");
  process.exit(77);
}
fs.mkdirSync(outDir, {recursive: true});
const nodeDir = path.join(outDir, "npm");  // shared with kiosk_session.mjs
if (!fs.existsSync(path.join(nodeDir, "node_modules", "playwright-core"))) {
  fs.mkdirSync(nodeDir, {recursive: true});
  console.log("installing playwright-core into", nodeDir);
  execFileSync("npm", ["install", "--no-audit", "--no-fund", "--prefix", nodeDir,
                       "playwright-core@1"], {stdio: "inherit"});
}
const require = createRequire(path.join(nodeDir, "package.json"));
const {chromium} = require("playwright-core");

const work = path.join(outDir, "calibration");
fs.rmSync(work, {recursive: true, force: true});
fs.mkdirSync(work, {recursive: true});
fs.writeFileSync(path.join(work, "faceboothd.toml"), `
[camera]
uri = "synthetic:seed=11,reg_dy=-14"
capture_frames = 8
realtime = false
preview_fps = 10.0
[storage]
data_dir = "${path.join(work, "data")}"
[http]
port = 0
[session]
guide_file = "${guideFile}"
`);
const daemon = spawn(daemonBin, ["--config", path.join(work, "faceboothd.toml")],
                     {stdio: ["ignore", "inherit", "pipe"]});
const port = await new Promise((resolve, reject) => {
  let text = "";
  daemon.stderr.on("data", (chunk) => {
    process.stderr.write(chunk);
    if (text === null) return;
    text += chunk;
    const m = text.match(/http 127\.0\.0\.1:(\d+)\)/);
    if (m) {
      text = null;
      resolve(Number(m[1]));
    }
  });
  daemon.on("exit", (code) => reject(new Error(`faceboothd exited (${code}) before it was ready`)));
  setTimeout(() => reject(new Error("faceboothd named no HTTP port within 60 s")), 60000);
});
const base = `http://127.0.0.1:${port}`;
let failed = null;
const browser = await chromium.launchPersistentContext(path.join(work, "chromium-profile"), {
  executablePath: CHROMIUM,
  headless: true,
  viewport: {width: 1280, height: 720},
  args: ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync"],
});
try {
  const page = await browser.newPage();
  await page.goto(base + "/");
  // The warning is visible (not just in the DOM) and says what to do.
  const banner = page.locator("#calibration");
  await banner.waitFor({state: "visible", timeout: 60000});
  const text = await banner.innerText();
  for (const needed of ["Camera needs calibration", "px apart", "Calibrate camera",
                        "facebooth camera calibrate"])
    if (!text.includes(needed)) throw new Error(`the warning lacks "${needed}": ${text}`);
  if (/nan/i.test(text)) throw new Error("the warning prints nan: " + text);
  const px = Number(await banner.getAttribute("data-px"));
  if (!(Math.abs(px - 14) <= 1.5)) throw new Error(`the page shows ${px} px, the unit is 14 px off`);
  if ((await page.getAttribute("#led", "class")) !== "led calibrate")
    throw new Error("the LED on the page is not the calibration pattern");
  await page.screenshot({path: path.join(outDir, "kiosk-needs-calibration.png")});
  // A session does not start; the page's message says why.
  await page.click("#start");
  await page.waitForFunction(() => document.querySelector("#message").textContent
                                        .startsWith("Session not started"), null, {timeout: 30000});
  // The page's button self-calibrates; the warning goes.
  await page.click("#calibrate");
  await banner.waitFor({state: "hidden", timeout: 120000});
  const result = await page.textContent("#calibration-result");
  if (!result.startsWith("Camera calibrated")) throw new Error("calibration said: " + result);
  let reg = null;
  for (let i = 0; i < 600; i++) {
    reg = (await (await fetch(base + "/api/status")).json()).registration;
    if (reg.state !== "checking") break;
    await page.waitForTimeout(100);
  }
  if (reg.state !== "ok" || !(reg.misregistration_px < 1.5))
    throw new Error("after calibration: " + JSON.stringify(reg));
  if (await banner.isVisible()) throw new Error("the warning is still shown after calibration");
  await page.screenshot({path: path.join(outDir, "kiosk-calibrated.png")});
  console.log(`warning shown at ${px} px; after the page's calibration ` +
              `${reg.misregistration_px.toFixed(2)} px; screenshots in ${outDir}`);
} catch (e) {
  failed = e;
} finally {
  await browser.close();
  daemon.kill("SIGTERM");
  await new Promise((r) => daemon.on("exit", r));
}
if (failed) { console.error("FAIL:", failed.message); process.exit(1); }
