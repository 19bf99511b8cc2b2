// Entry of the vendored bundle (three.bundle.min.js): three.js and the three
// add-ons the viewer uses, exposed as one global THREE so that a classic
// <script> inlined in a page opened from file:// can use them (module imports
// from file:// are blocked by Chromium's CORS rules).
export * from "three";
export { GLTFLoader } from "three/addons/loaders/GLTFLoader.js";
export { HDRLoader } from "three/addons/loaders/HDRLoader.js";
export { OrbitControls } from "three/addons/controls/OrbitControls.js";
