// The wire protocol's decoder for the browser (and node): one binary message to a plain object.
//
// It reads the layouts from the protocol's JSON (processes/network/wire/protocol.py layout_json, served
// by the web bridge as /protocol.json and embedded in a replay's HTML), so the offsets are the
// Python dtypes' own and cannot drift. The bridge forwards only messages its own decoder accepted;
// this one checks magic, version, kind and size, and reads the fields.

const TYPES = {
  f8: [8, (dv, at) => dv.getFloat64(at, true)],
  f4: [4, (dv, at) => dv.getFloat32(at, true)],
  u8: [8, (dv, at) => Number(dv.getBigUint64(at, true))],
  i8: [8, (dv, at) => Number(dv.getBigInt64(at, true))],
  u4: [4, (dv, at) => dv.getUint32(at, true)],
  u2: [2, (dv, at) => dv.getUint16(at, true)],
  i2: [2, (dv, at) => dv.getInt16(at, true)],
  u1: [1, (dv, at) => dv.getUint8(at)],
  i1: [1, (dv, at) => dv.getInt8(at)],
};

export class Decoder {
  constructor(protocol) {
    this.protocol = protocol;
    this.byKind = {};
    for (const [name, spec] of Object.entries(protocol.messages)) {
      this.byKind[spec.kind] = { name, ...spec };
    }
    this.utf8 = new TextDecoder("utf-8");
  }

  decode(buffer) {
    const bytes = buffer instanceof Uint8Array ? buffer : new Uint8Array(buffer);
    const dv = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
    if (bytes.byteLength < 24) throw new Error(`${bytes.byteLength} bytes, shorter than the header`);
    const magic = String.fromCharCode(...bytes.subarray(0, 4));
    if (magic !== this.protocol.magic) throw new Error(`magic ${magic}`);
    const version = dv.getUint16(4, true);
    if (version !== this.protocol.version) throw new Error(`protocol version ${version}`);
    const spec = this.byKind[dv.getUint8(6)];
    if (spec === undefined) throw new Error(`message type ${dv.getUint8(6)}`);
    if (bytes.byteLength !== spec.size) throw new Error(`${spec.name}: ${bytes.byteLength} bytes, expected ${spec.size}`);
    const out = { kind: spec.name, flags: dv.getUint8(7), seq: Number(dv.getBigUint64(8, true)),
                  tick: Number(dv.getBigInt64(16, true)) };
    for (const field of spec.fields) {
      out[field.name] = this.field(bytes, dv, field);
    }
    return out;
  }

  field(bytes, dv, field) {
    const count = field.shape.reduce((a, b) => a * b, 1);
    if (field.kind === "text") {
      const raw = bytes.subarray(field.offset, field.offset + count);
      const end = raw.indexOf(0);
      return this.utf8.decode(end < 0 ? raw : raw.subarray(0, end));
    }
    if (field.kind === "token") {
      return Array.from(bytes.subarray(field.offset, field.offset + count), (b) => b.toString(16).padStart(2, "0")).join("");
    }
    const [size, read] = TYPES[field.type];
    if (field.shape.length === 0) return read(dv, field.offset);
    const flat = [];
    for (let i = 0; i < count; i++) flat.push(read(dv, field.offset + i * size));
    if (field.shape.length === 1) return flat;
    const rows = [];  // two dimensions at most on this wire (bat_pos: 2 x 3, net offset: 640 x 3)
    const width = field.shape[1];
    for (let i = 0; i < field.shape[0]; i++) rows.push(flat.slice(i * width, (i + 1) * width));
    return rows;
  }

  name(enumName, value) {
    return this.protocol.enums[enumName][String(value)];
  }
}
