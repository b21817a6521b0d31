// Runs a TensorFlow.js graph model once in the real tfjs runtime (pure-JS CPU backend) and
// writes its raw outputs: the reference that tests/test_detect.py checks jeanscv's torch
// executor against. Documentation of how the fixture was made; never run by the tests.
//
//   cd /tmp/detector-work && npm install @tensorflow/tfjs@4.22.0
//   NODE_PATH=/tmp/detector-work/node_modules node reference.js MODEL.json INPUT.f32 SHAPE OUTDIR OUTPUT...
//
// INPUT.f32: the graph input, float32 little-endian; SHAPE: e.g. 1,3,416,416. Each output
// is written to OUTDIR/<index>.f32 (float32 little-endian) with its shape on stdout.
const fs = require('fs');
const path = require('path');
const tf = require('@tensorflow/tfjs');

async function main() {
  const [modelJson, inputFile, shapeText, outDir, ...outputs] = process.argv.slice(2);
  await tf.setBackend('cpu');
  const model = JSON.parse(fs.readFileSync(modelJson, 'utf8'));
  const weightSpecs = model.weightsManifest.flatMap((group) => group.weights);
  const buffers = model.weightsManifest.flatMap((group) => group.paths.map((p) => fs.readFileSync(path.join(path.dirname(modelJson), p))));
  const joined = Buffer.concat(buffers);
  const weightData = joined.buffer.slice(joined.byteOffset, joined.byteOffset + joined.byteLength);
  const graph = await tf.loadGraphModel(tf.io.fromMemory({ modelTopology: model.modelTopology, weightSpecs, weightData, format: model.format }));
  const raw = fs.readFileSync(inputFile);
  const input = tf.tensor(new Float32Array(raw.buffer, raw.byteOffset, raw.byteLength / 4), shapeText.split(',').map(Number), 'float32');
  const result = graph.execute(input, outputs);
  const tensors = Array.isArray(result) ? result : [result];
  fs.mkdirSync(outDir, { recursive: true });
  tensors.forEach((t, i) => {
    fs.writeFileSync(path.join(outDir, `${i}.f32`), Buffer.from(t.dataSync().buffer));
    console.log(outputs[i], JSON.stringify(t.shape));
  });
}
main();
