// FreqBRDF capture viewer: the ground truth and every method's exported material
// side by side, one camera for all panels, lit by a selectable environment map.
// Everything comes inlined in the page (freqbrdf.viewer): classic scripts and
// no fetches, because Chromium blocks module imports and fetch() from file://.
"use strict";
(function () {
  const body = document.body;
  function setStatus(state, message) {
    body.dataset.status = state;
    document.getElementById("status").textContent = message;
  }
  window.addEventListener("error", (event) => setStatus("error", "error: " + event.message));

  const data = JSON.parse(document.getElementById("freqbrdf-data").textContent);

  function bytes(base64) {
    const text = atob(base64);
    const out = new Uint8Array(text.length);
    for (let i = 0; i < text.length; i++) out[i] = text.charCodeAt(i);
    return out;
  }

  const stage = document.getElementById("stage");
  const grid = document.getElementById("panels");
  grid.style.setProperty("--panel-size", data.panel_size + "px");
  const canvas = document.getElementById("canvas");
  // preserveDrawingBuffer: a screenshot taken between frames still shows the last one.
  const renderer = new THREE.WebGLRenderer({ canvas: canvas, antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio);
  renderer.setScissorTest(true);
  renderer.setClearColor(new THREE.Color(data.background), 1);
  renderer.toneMapping = THREE.NeutralToneMapping;

  const camera = new THREE.PerspectiveCamera(data.camera.fov_deg, 1, 0.05, 100);
  camera.position.fromArray(data.camera.position);
  const controls = new THREE.OrbitControls(camera, grid);
  controls.target.set(0, 0, 0);
  controls.autoRotateSpeed = 1.5;
  controls.update();

  const panels = data.panels.map((panel) => {
    const figure = document.createElement("figure");
    figure.className = "panel";
    figure.dataset.name = panel.name;
    const view = document.createElement("div");
    view.className = "view";
    const caption = document.createElement("figcaption");
    caption.textContent = panel.label;
    figure.append(view, caption);
    grid.append(figure);
    return { name: panel.name, uncertainty: panel.uncertainty, view: view, scene: new THREE.Scene(), overlay: null };
  });

  // Environment maps, decoded and prefiltered for image-based lighting on first use.
  const pmrem = new THREE.PMREMGenerator(renderer);
  const environments = {};
  function environment(name) {
    if (environments[name] === undefined) {
      const hdr = new THREE.HDRLoader().setDataType(THREE.FloatType).parse(bytes(data.envs[name]).buffer);
      const width = hdr.width, height = hdr.height, pixels = hdr.data;
      // Our maps are in Mitsuba's equirectangular layout (u = 0 looks along -Z,
      // u = 1/4 along +X); three.js puts u = 1/2 along +X. Shifting every row a
      // quarter turn to the right makes each direction fetch the same radiance.
      const shifted = new Float32Array(pixels.length);
      const shift = Math.round(width / 4);
      for (let row = 0; row < height; row++) {
        for (let col = 0; col < width; col++) {
          const from = 4 * (row * width + col), to = 4 * (row * width + ((col + shift) % width));
          for (let c = 0; c < 4; c++) shifted[to + c] = pixels[from + c];
        }
      }
      const texture = new THREE.DataTexture(shifted, width, height, THREE.RGBAFormat, THREE.FloatType);
      texture.flipY = true; // .hdr rows run top (up) to bottom, as three.js's own HDR loading assumes
      texture.mapping = THREE.EquirectangularReflectionMapping;
      texture.minFilter = THREE.LinearFilter;
      texture.magFilter = THREE.LinearFilter;
      texture.generateMipmaps = false;
      texture.needsUpdate = true;
      environments[name] = pmrem.fromEquirectangular(texture).texture;
      texture.dispose();
    }
    return environments[name];
  }

  const envSelect = document.getElementById("env");
  for (const name of Object.keys(data.envs)) envSelect.add(new Option(name, name));
  const rotate = document.getElementById("rotate");
  const layer = document.getElementById("overlay");
  const opacity = document.getElementById("opacity");
  const exposure = document.getElementById("exposure");
  // Settings from the address (#env=NAME&rotate=0&overlay=uncertainty), read again when it changes,
  // so that a link opens the page as shown and a test can switch settings without reloading.
  function readAddress() {
    const options = new URLSearchParams(window.location.hash.slice(1));
    if (options.has("env") && options.get("env") in data.envs) envSelect.value = options.get("env");
    rotate.checked = options.get("rotate") !== "0";
    layer.value = ["uncertainty", "entropy"].includes(options.get("overlay")) ? options.get("overlay") : "off";
  }
  readAddress();

  const overlayTextures = {}; // overlay name -> texture, filled by load()
  function applySettings() {
    const env = environment(envSelect.value);
    for (const panel of panels) {
      panel.scene.environment = env;
      if (panel.overlay !== null) {
        const shown = layer.value === "entropy" ? data.entropy : panel.uncertainty;
        panel.overlay.visible = layer.value !== "off";
        panel.overlay.material.map = overlayTextures[shown];
        panel.overlay.material.opacity = Number(opacity.value);
      }
    }
    controls.autoRotate = rotate.checked;
    renderer.toneMappingExposure = Math.pow(2, Number(exposure.value));
  }
  for (const input of [envSelect, rotate, layer, opacity, exposure]) input.addEventListener("input", applySettings);
  window.addEventListener("hashchange", () => {
    readAddress();
    if (body.dataset.status === "ready") applySettings();
  });

  function draw() {
    const width = grid.clientWidth, height = grid.clientHeight;
    canvas.style.left = grid.offsetLeft + "px";
    canvas.style.top = grid.offsetTop + "px";
    renderer.setSize(width, height, false);
    canvas.style.width = width + "px";
    canvas.style.height = height + "px";
    const origin = grid.getBoundingClientRect();
    for (const panel of panels) {
      const rect = panel.view.getBoundingClientRect();
      const left = rect.left - origin.left, bottom = origin.bottom - rect.bottom;
      renderer.setViewport(left, bottom, rect.width, rect.height);
      renderer.setScissor(left, bottom, rect.width, rect.height);
      camera.aspect = rect.width / rect.height;
      camera.updateProjectionMatrix();
      renderer.render(panel.scene, camera);
    }
  }

  function loop() {
    controls.update();
    draw();
    requestAnimationFrame(loop);
  }

  async function load() {
    const gltf = await new THREE.GLTFLoader().parseAsync(bytes(data.scene).buffer, "");
    for (const [name, png] of Object.entries(data.overlays)) {
      const texture = await new THREE.TextureLoader().loadAsync("data:image/png;base64," + png);
      texture.flipY = false; // glTF's uv convention, as the model's own textures
      texture.colorSpace = THREE.SRGBColorSpace;
      overlayTextures[name] = texture;
    }
    for (const panel of panels) {
      // three.js sanitises object names; the node's name as written is kept in userData.
      let node;
      gltf.scene.traverse((object) => { if (node === undefined && object.userData.name === panel.name) node = object; });
      if (node === undefined) throw new Error("the model has no node " + panel.name);
      panel.scene.add(node);
      if (panel.uncertainty !== null) {
        const material = new THREE.MeshBasicMaterial({
          map: overlayTextures[panel.uncertainty], transparent: true, depthWrite: false, toneMapped: false,
          polygonOffset: true, polygonOffsetFactor: -1, polygonOffsetUnits: -1,
        });
        const mesh = new THREE.Mesh(node.geometry, material);
        node.add(mesh);
        panel.overlay = mesh;
      }
    }
    applySettings();
    draw();
    // The panels' places, for tests that look at a screenshot of the page.
    body.dataset.panels = JSON.stringify(panels.map((panel) => {
      const r = panel.view.getBoundingClientRect();
      return { name: panel.name, left: r.left, top: r.top, width: r.width, height: r.height };
    }));
    setStatus("ready", panels.length + " models loaded");
    requestAnimationFrame(loop);
  }
  load().catch((error) => setStatus("error", "error: " + error.message));
})();
