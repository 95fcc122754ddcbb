// The tests read pictures (screenshots, slices) with the gateway's own PNG decoder (web/gateway/png.ts).
export { decodePng } from "../gateway/png.js";
