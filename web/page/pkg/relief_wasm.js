/**
 * A held tile's triangles in world metres.
 */
export class TileGeometry {
    static __wrap(ptr) {
        const obj = Object.create(TileGeometry.prototype);
        obj.__wbg_ptr = ptr;
        TileGeometryFinalization.register(obj, obj.__wbg_ptr, obj);
        return obj;
    }
    __destroy_into_raw() {
        const ptr = this.__wbg_ptr;
        this.__wbg_ptr = 0;
        TileGeometryFinalization.unregister(this);
        return ptr;
    }
    free() {
        const ptr = this.__destroy_into_raw();
        wasm.__wbg_tilegeometry_free(ptr, 0);
    }
    /**
     * Crack patch or skirt triangles (the indices after the mesh's).
     * @returns {number}
     */
    get extra_triangles() {
        const ret = wasm.tilegeometry_extra_triangles(this.__wbg_ptr);
        return ret >>> 0;
    }
    /**
     * Triangle indices: the mesh's, then the crack patches' (or skirts'), three per triangle.
     * @returns {Uint32Array}
     */
    indices() {
        const ret = wasm.tilegeometry_indices(this.__wbg_ptr);
        var v1 = getArrayU32FromWasm0(ret[0], ret[1]).slice();
        wasm.__wbindgen_free(ret[0], ret[1] * 4, 4);
        return v1;
    }
    /**
     * The tile's level in the pyramid (0 is the root tile).
     * @returns {number}
     */
    get level() {
        const ret = wasm.tilegeometry_level(this.__wbg_ptr);
        return ret;
    }
    /**
     * Triangles of the tile's own surface (the first `3 * mesh_triangles` indices).
     * @returns {number}
     */
    get mesh_triangles() {
        const ret = wasm.tilegeometry_mesh_triangles(this.__wbg_ptr);
        return ret >>> 0;
    }
    /**
     * Smooth normals, four floats a vertex: `x, y` of the unit upward normal of the tile's own
     * mesh, then of the morph target's (`z` follows, as they point up); `0, 0` on the
     * vertices of patches and skirts alone.
     * @returns {Float32Array}
     */
    normals() {
        const ret = wasm.tilegeometry_normals(this.__wbg_ptr);
        var v1 = getArrayF32FromWasm0(ret[0], ret[1]).slice();
        wasm.__wbindgen_free(ret[0], ret[1] * 4, 4);
        return v1;
    }
    /**
     * Vertices, four floats each: `x, y, z` world metres (x east, y north, z up), then the
     * morph target's `z` (the height on the parent's mesh; `z` itself where the vertex never
     * moves).
     * @returns {Float32Array}
     */
    positions() {
        const ret = wasm.tilegeometry_positions(this.__wbg_ptr);
        var v1 = getArrayF32FromWasm0(ret[0], ret[1]).slice();
        wasm.__wbindgen_free(ret[0], ret[1] * 4, 4);
        return v1;
    }
}
if (Symbol.dispose) TileGeometry.prototype[Symbol.dispose] = TileGeometry.prototype.free;

/**
 * A tile session's state, without the socket.
 */
export class TileSession {
    __destroy_into_raw() {
        const ptr = this.__wbg_ptr;
        this.__wbg_ptr = 0;
        TileSessionFinalization.unregister(this);
        return ptr;
    }
    free() {
        const ptr = this.__destroy_into_raw();
        wasm.__wbg_tilesession_free(ptr, 0);
    }
    /**
     * The acknowledgement of every delta applied on this connection.
     * @returns {Uint8Array}
     */
    ack() {
        const ret = wasm.tilesession_ack(this.__wbg_ptr);
        var v1 = getArrayU8FromWasm0(ret[0], ret[1]).slice();
        wasm.__wbindgen_free(ret[0], ret[1] * 1, 1);
        return v1;
    }
    /**
     * The active tiles, ascending.
     * @returns {Uint32Array}
     */
    active() {
        const ret = wasm.tilesession_active(this.__wbg_ptr);
        var v1 = getArrayU32FromWasm0(ret[0], ret[1]).slice();
        wasm.__wbindgen_free(ret[0], ret[1] * 4, 4);
        return v1;
    }
    /**
     * Vertex stream: active nodes of the cut.
     * @returns {number}
     */
    get active_nodes() {
        const ret = wasm.tilesession_active_nodes(this.__wbg_ptr);
        return ret;
    }
    /**
     * Tiles the last delta started drawing.
     * @returns {Uint32Array}
     */
    added() {
        const ret = wasm.tilesession_added(this.__wbg_ptr);
        var v1 = getArrayU32FromWasm0(ret[0], ret[1]).slice();
        wasm.__wbindgen_free(ret[0], ret[1] * 4, 4);
        return v1;
    }
    /**
     * The newest pose a delta answered.
     * @returns {number}
     */
    get answered_pose() {
        const ret = wasm.tilesession_answered_pose(this.__wbg_ptr);
        return ret;
    }
    /**
     * The newest delta applied on this connection.
     * @returns {number}
     */
    get applied() {
        const ret = wasm.tilesession_applied(this.__wbg_ptr);
        return ret;
    }
    /**
     * Vertex stream: cell records to draw (each two triangles, six corners, of node slots).
     * @returns {number}
     */
    get cell_count() {
        const ret = wasm.tilesession_cell_count(this.__wbg_ptr);
        return ret >>> 0;
    }
    /**
     * Whether the newest delta met tau for its pose.
     * @returns {boolean}
     */
    get complete() {
        const ret = wasm.tilesession_complete(this.__wbg_ptr);
        return ret !== 0;
    }
    /**
     * Digest of the active tiles or the cut, 16 hex digits.
     * @returns {string}
     */
    get digest() {
        let deferred1_0;
        let deferred1_1;
        try {
            const ret = wasm.tilesession_digest(this.__wbg_ptr);
            deferred1_0 = ret[0];
            deferred1_1 = ret[1];
            return getStringFromWasm0(ret[0], ret[1]);
        } finally {
            wasm.__wbindgen_free(deferred1_0, deferred1_1, 1);
        }
    }
    /**
     * Tiles the last delta dropped from the cache (their geometry is no longer needed).
     * @returns {Uint32Array}
     */
    evicted() {
        const ret = wasm.tilesession_evicted(this.__wbg_ptr);
        var v1 = getArrayU32FromWasm0(ret[0], ret[1]).slice();
        wasm.__wbindgen_free(ret[0], ret[1] * 4, 4);
        return v1;
    }
    /**
     * Vertex stream: the triangles of the fans.
     * @returns {number}
     */
    get fan_triangles() {
        const ret = wasm.tilesession_fan_triangles(this.__wbg_ptr);
        return ret >>> 0;
    }
    /**
     * The triangles of held tile `index`, mesh then patches or skirts; `undefined` for a tile
     * not held.
     * @param {number} index
     * @returns {TileGeometry | undefined}
     */
    geometry(index) {
        const ret = wasm.tilesession_geometry(this.__wbg_ptr, index);
        return ret === 0 ? undefined : TileGeometry.__wrap(ret);
    }
    /**
     * Lowest and highest terrain height, metres (`[0, 0]` before the welcome).
     * @returns {Float32Array}
     */
    height_range() {
        const ret = wasm.tilesession_height_range(this.__wbg_ptr);
        var v1 = getArrayF32FromWasm0(ret[0], ret[1]).slice();
        wasm.__wbindgen_free(ret[0], ret[1] * 4, 4);
        return v1;
    }
    /**
     * Tiles held, active and cached; on the vertex stream, the nodes held.
     * @returns {number}
     */
    get held() {
        const ret = wasm.tilesession_held(this.__wbg_ptr);
        return ret >>> 0;
    }
    /**
     * The hello for a new connection: a resume from the mirror (the active tiles when it holds
     * any, the cut), else a new session.
     * @returns {Uint8Array}
     */
    hello() {
        const ret = wasm.tilesession_hello(this.__wbg_ptr);
        var v1 = getArrayU8FromWasm0(ret[0], ret[1]).slice();
        wasm.__wbindgen_free(ret[0], ret[1] * 1, 1);
        return v1;
    }
    /**
     * The server closes a connection silent for this long, milliseconds.
     * @returns {number}
     */
    get idle_timeout_ms() {
        const ret = wasm.tilesession_idle_timeout_ms(this.__wbg_ptr);
        return ret >>> 0;
    }
    /**
     * Deltas the server lets out unacknowledged.
     * @returns {number}
     */
    get max_in_flight() {
        const ret = wasm.tilesession_max_in_flight(this.__wbg_ptr);
        return ret >>> 0;
    }
    /**
     * Vertex stream: what the vertex shader's geomorph needs of the view from eye `x, y, z`
     * looking along `yaw`, `pitch` (radians) through this session's lens, 32 floats: the unit
     * view direction and the focal length in pixels; the inward normals of the four side
     * planes and the near plane, each with its offset; tau, lambda, the growth duration in
     * seconds and the off-axis bound; the near distance and three zeros. The same
     * `relief_proto::view::ViewState` as the server's and the wgpu client's (`frame.rs`).
     * @param {number} x
     * @param {number} y
     * @param {number} z
     * @param {number} yaw
     * @param {number} pitch
     * @returns {Float32Array}
     */
    morph_block(x, y, z, yaw, pitch) {
        const ret = wasm.tilesession_morph_block(this.__wbg_ptr, x, y, z, yaw, pitch);
        var v1 = getArrayF32FromWasm0(ret[0], ret[1]).slice();
        wasm.__wbindgen_free(ret[0], ret[1] * 4, 4);
        return v1;
    }
    /**
     * A session for a `width` x `height` pixel viewport with a vertical field of view of
     * `fov_y_deg` degrees and a near plane `near` metres away, screen error `tau` pixels, on
     * `stream` `tiles` (then `crack` is one of `patches`, `skirts`, `none`, and at most
     * `cache_tiles` tiles are kept) or `vertex`.
     * @param {number} width
     * @param {number} height
     * @param {number} fov_y_deg
     * @param {number} near
     * @param {number} tau
     * @param {string} stream
     * @param {string} crack
     * @param {number} cache_tiles
     */
    constructor(width, height, fov_y_deg, near, tau, stream, crack, cache_tiles) {
        const val3 = +width;
        const val4 = +height;
        const val5 = +fov_y_deg;
        const val6 = +near;
        const val7 = +tau;
        const val8 = +cache_tiles;
        let ptr0, len0, ptr1, len1;
        try {
            ptr0 = passStringToWasm0(stream, wasm.__wbindgen_malloc, wasm.__wbindgen_realloc);
            len0 = WASM_VECTOR_LEN;
            ptr1 = passStringToWasm0(crack, wasm.__wbindgen_malloc, wasm.__wbindgen_realloc);
            len1 = WASM_VECTOR_LEN;
        } catch (e) {
            if (ptr1) { wasm.__wbindgen_free(ptr1, len1 * 1, 1); }
            if (ptr0) { wasm.__wbindgen_free(ptr0, len0 * 1, 1); }
            throw e;
        }
        const ret = wasm.tilesession_new(val3, val4, val5, val6, val7, ptr0, len0, ptr1, len1, val8);
        if (ret[2]) {
            throw takeFromExternrefTable0(ret[1]);
        }
        this.__wbg_ptr = ret[0];
        TileSessionFinalization.register(this, this.__wbg_ptr, this);
        return this;
    }
    /**
     * A pose: eye `x, y, z` world metres, `yaw` and `pitch` radians; numbered from 1.
     * @param {number} x
     * @param {number} y
     * @param {number} z
     * @param {number} yaw
     * @param {number} pitch
     * @returns {Uint8Array}
     */
    pose(x, y, z, yaw, pitch) {
        const ret = wasm.tilesession_pose(this.__wbg_ptr, x, y, z, yaw, pitch);
        var v1 = getArrayU8FromWasm0(ret[0], ret[1]).slice();
        wasm.__wbindgen_free(ret[0], ret[1] * 1, 1);
        return v1;
    }
    /**
     * The last pose's sequence number.
     * @returns {number}
     */
    get pose_seq() {
        const ret = wasm.tilesession_pose_seq(this.__wbg_ptr);
        return ret;
    }
    /**
     * Decodes and applies one server message at `now` (seconds on the page's drawing clock:
     * the split time of the vertex stream's geomorph). Returns `welcome` (a new session: drop
     * everything drawn), `resumed` (the active tiles or the cut stay; cached tiles are gone),
     * `delta` (see [`Self::removed`], [`Self::added`], [`Self::evicted`], or the vertex
     * stream's record rows) or `reconnect` (close, wait [`Self::reconnect_after_ms`],
     * reconnect). An error is a desync or a protocol fault: close, [`Self::reset`] and
     * reconnect.
     * @param {Uint8Array | number[]} bytes
     * @param {number} now
     * @returns {string}
     */
    receive(bytes, now) {
        let deferred4_0;
        let deferred4_1;
        try {
            const val2 = +now;
            const ptr0 = passArray8ToWasm0(bytes, wasm.__wbindgen_malloc);
            const len0 = WASM_VECTOR_LEN;
            const ret = wasm.tilesession_receive(this.__wbg_ptr, ptr0, len0, val2);
            var ptr3 = ret[0];
            var len3 = ret[1];
            if (ret[3]) {
                ptr3 = 0; len3 = 0;
                throw takeFromExternrefTable0(ret[2]);
            }
            deferred4_0 = ptr3;
            deferred4_1 = len3;
            return getStringFromWasm0(ptr3, len3);
        } finally {
            wasm.__wbindgen_free(deferred4_0, deferred4_1, 1);
        }
    }
    /**
     * The wait the last `Reconnect` asked for, milliseconds.
     * @returns {number}
     */
    get reconnect_after_ms() {
        const ret = wasm.tilesession_reconnect_after_ms(this.__wbg_ptr);
        return ret >>> 0;
    }
    /**
     * Tiles the last delta stopped drawing (dense indices).
     * @returns {Uint32Array}
     */
    removed() {
        const ret = wasm.tilesession_removed(this.__wbg_ptr);
        var v1 = getArrayU32FromWasm0(ret[0], ret[1]).slice();
        wasm.__wbindgen_free(ret[0], ret[1] * 4, 4);
        return v1;
    }
    /**
     * Forgets the mirror: the next hello starts a new session (after a desync, or a resume the
     * server refused).
     */
    reset() {
        wasm.tilesession_reset(this.__wbg_ptr);
    }
    /**
     * Whether the next hello resumes.
     * @returns {boolean}
     */
    get resuming() {
        const ret = wasm.tilesession_resuming(this.__wbg_ptr);
        return ret !== 0;
    }
    /**
     * Tiles of the last delta that came with a body (the others came from the cache); on the
     * vertex stream, the delta's splits and merges.
     * @returns {number}
     */
    get sent() {
        const ret = wasm.tilesession_sent(this.__wbg_ptr);
        return ret >>> 0;
    }
    /**
     * The welcome's session id, 16 hex digits.
     * @returns {string}
     */
    get session_id() {
        let deferred1_0;
        let deferred1_1;
        try {
            const ret = wasm.tilesession_session_id(this.__wbg_ptr);
            deferred1_0 = ret[0];
            deferred1_1 = ret[1];
            return getStringFromWasm0(ret[0], ret[1]);
        } finally {
            wasm.__wbindgen_free(deferred1_0, deferred1_1, 1);
        }
    }
    /**
     * Changes the viewport and tau for the next hello (they are fixed for a connection).
     * @param {number} width
     * @param {number} height
     * @param {number} tau
     */
    set_view(width, height, tau) {
        wasm.tilesession_set_view(this.__wbg_ptr, width, height, tau);
    }
    /**
     * The tiles among [`Self::added`] that replaced a coarser tile the same delta removed (an
     * ancestor): they morph in from their parent's mesh. The others arrived by a merge.
     * @returns {Uint32Array}
     */
    split_added() {
        const ret = wasm.tilesession_split_added(this.__wbg_ptr);
        var v1 = getArrayU32FromWasm0(ret[0], ret[1]).slice();
        wasm.__wbindgen_free(ret[0], ret[1] * 4, 4);
        return v1;
    }
    /**
     * Vertex stream: the cell records' rows that changed since the last call, for an R32UI
     * texture of 4096 texels a row (a node slot each, six a cell; `u32::MAX` for a missing
     * triangle), laid out as [`Self::take_node_rows`].
     * @returns {Uint32Array}
     */
    take_cell_rows() {
        const ret = wasm.tilesession_take_cell_rows(this.__wbg_ptr);
        var v1 = getArrayU32FromWasm0(ret[0], ret[1]).slice();
        wasm.__wbindgen_free(ret[0], ret[1] * 4, 4);
        return v1;
    }
    /**
     * Vertex stream: the node records' rows that changed since the last call, for an RGBA32UI
     * texture of 768 texels a row (256 records of 12 words, see
     * `relief_proto::mesh::scene::NODE_WORDS`): `[rows in all, then per run: first row, row
     * count, the rows' words]`. All rows after a welcome or when the pool grew.
     * @returns {Uint32Array}
     */
    take_node_rows() {
        const ret = wasm.tilesession_take_node_rows(this.__wbg_ptr);
        var v1 = getArrayU32FromWasm0(ret[0], ret[1]).slice();
        wasm.__wbindgen_free(ret[0], ret[1] * 4, 4);
        return v1;
    }
    /**
     * Whether the session has been welcomed.
     * @returns {boolean}
     */
    get welcomed() {
        const ret = wasm.tilesession_welcomed(this.__wbg_ptr);
        return ret !== 0;
    }
}
if (Symbol.dispose) TileSession.prototype[Symbol.dispose] = TileSession.prototype.free;

/**
 * The poses of camera path `kind`, five numbers each (`x, y, z, yaw, pitch`), with `heights`
 * the ground's heights at [`camera_path_queries`]' points, in order.
 * @param {string} kind
 * @param {number} extent_x
 * @param {number} extent_y
 * @param {Float32Array | number[]} heights
 * @returns {Float32Array}
 */
export function camera_path_poses(kind, extent_x, extent_y, heights) {
    const val3 = +extent_x;
    const val4 = +extent_y;
    let ptr0, len0, ptr1, len1;
    try {
        ptr0 = passStringToWasm0(kind, wasm.__wbindgen_malloc, wasm.__wbindgen_realloc);
        len0 = WASM_VECTOR_LEN;
        ptr1 = passArrayF32ToWasm0(heights, wasm.__wbindgen_malloc);
        len1 = WASM_VECTOR_LEN;
    } catch (e) {
        if (ptr1) { wasm.__wbindgen_free(ptr1, len1 * 4, 4); }
        if (ptr0) { wasm.__wbindgen_free(ptr0, len0 * 1, 1); }
        throw e;
    }
    const ret = wasm.camera_path_poses(ptr0, len0, val3, val4, ptr1, len1);
    if (ret[3]) {
        throw takeFromExternrefTable0(ret[2]);
    }
    var v5 = getArrayF32FromWasm0(ret[0], ret[1]).slice();
    wasm.__wbindgen_free(ret[0], ret[1] * 4, 4);
    return v5;
}

/**
 * The points, `x, y` interleaved, at which the camera path `kind` (`standard` or `stress`)
 * over a terrain of `extent_x` by `extent_y` metres needs the ground's height: ask the server
 * (`POST /v1/heights`), then call [`camera_path_poses`] with the answers in this order.
 * @param {string} kind
 * @param {number} extent_x
 * @param {number} extent_y
 * @returns {Float32Array}
 */
export function camera_path_queries(kind, extent_x, extent_y) {
    const val2 = +extent_x;
    const val3 = +extent_y;
    const ptr0 = passStringToWasm0(kind, wasm.__wbindgen_malloc, wasm.__wbindgen_realloc);
    const len0 = WASM_VECTOR_LEN;
    const ret = wasm.camera_path_queries(ptr0, len0, val2, val3);
    if (ret[3]) {
        throw takeFromExternrefTable0(ret[2]);
    }
    var v4 = getArrayF32FromWasm0(ret[0], ret[1]).slice();
    wasm.__wbindgen_free(ret[0], ret[1] * 4, 4);
    return v4;
}

/**
 * Whether a close with `code` refused the resume snapshot (reconnect without it).
 * @param {number} code
 * @returns {boolean}
 */
export function close_refused_snapshot(code) {
    const ret = wasm.close_refused_snapshot(code);
    return ret !== 0;
}

/**
 * Whether a close with `code` is worth reconnecting after (protocol section 10): a network
 * failure, a code that is not the protocol's, or one the protocol marks retry.
 * @param {number} code
 * @returns {boolean}
 */
export function close_retries(code) {
    const ret = wasm.close_retries(code);
    return ret !== 0;
}

/**
 * The protocol version this page speaks.
 * @returns {number}
 */
export function protocol_version() {
    const ret = wasm.protocol_version();
    return ret >>> 0;
}
function __wbg_get_imports() {
    const import0 = {
        __proto__: null,
        __wbg_Error_208446807d0d1e30: function(arg0, arg1) {
            const ret = Error(getStringFromWasm0(arg0, arg1));
            return ret;
        },
        __wbg___wbindgen_throw_4c88d8bf264fd984: function(arg0, arg1) {
            throw new Error(getStringFromWasm0(arg0, arg1));
        },
        __wbindgen_init_externref_table: function() {
            const table = wasm.__wbindgen_externrefs;
            table.set(0, undefined);
            table.set(1024, undefined);
            table.set(1025, null);
            table.set(1026, true);
            table.set(1027, false);
        },
    };
    return {
        __proto__: null,
        "./relief_wasm_bg.js": import0,
    };
}

const TileGeometryFinalization = (typeof FinalizationRegistry === 'undefined')
    ? { register: () => {}, unregister: () => {} }
    : new FinalizationRegistry(ptr => wasm.__wbg_tilegeometry_free(ptr, 1));
const TileSessionFinalization = (typeof FinalizationRegistry === 'undefined')
    ? { register: () => {}, unregister: () => {} }
    : new FinalizationRegistry(ptr => wasm.__wbg_tilesession_free(ptr, 1));

function getArrayF32FromWasm0(ptr, len) {
    ptr = ptr >>> 0;
    return getFloat32ArrayMemory0().subarray(ptr / 4, ptr / 4 + len);
}

function getArrayU32FromWasm0(ptr, len) {
    ptr = ptr >>> 0;
    return getUint32ArrayMemory0().subarray(ptr / 4, ptr / 4 + len);
}

function getArrayU8FromWasm0(ptr, len) {
    ptr = ptr >>> 0;
    return getUint8ArrayMemory0().subarray(ptr / 1, ptr / 1 + len);
}

let cachedFloat32ArrayMemory0 = null;
function getFloat32ArrayMemory0() {
    if (cachedFloat32ArrayMemory0 === null || cachedFloat32ArrayMemory0.byteLength === 0) {
        cachedFloat32ArrayMemory0 = new Float32Array(wasm.memory.buffer);
    }
    return cachedFloat32ArrayMemory0;
}

function getStringFromWasm0(ptr, len) {
    ptr = ptr >>> 0;
    return decodeText(getUint8ArrayMemory0().subarray(ptr, ptr + len));
}

let cachedUint32ArrayMemory0 = null;
function getUint32ArrayMemory0() {
    if (cachedUint32ArrayMemory0 === null || cachedUint32ArrayMemory0.byteLength === 0) {
        cachedUint32ArrayMemory0 = new Uint32Array(wasm.memory.buffer);
    }
    return cachedUint32ArrayMemory0;
}

let cachedUint8ArrayMemory0 = null;
function getUint8ArrayMemory0() {
    if (cachedUint8ArrayMemory0 === null || cachedUint8ArrayMemory0.byteLength === 0) {
        cachedUint8ArrayMemory0 = new Uint8Array(wasm.memory.buffer);
    }
    return cachedUint8ArrayMemory0;
}

function passArray8ToWasm0(arg, malloc) {
    const ptr = malloc(arg.length * 1, 1) >>> 0;
    getUint8ArrayMemory0().set(arg, ptr / 1);
    WASM_VECTOR_LEN = arg.length;
    return ptr;
}

function passArrayF32ToWasm0(arg, malloc) {
    const ptr = malloc(arg.length * 4, 4) >>> 0;
    getFloat32ArrayMemory0().set(arg, ptr / 4);
    WASM_VECTOR_LEN = arg.length;
    return ptr;
}

function passStringToWasm0(arg, malloc, realloc) {
    if (realloc === undefined) {
        const buf = cachedTextEncoder.encode(arg);
        const ptr = malloc(buf.length, 1) >>> 0;
        getUint8ArrayMemory0().subarray(ptr, ptr + buf.length).set(buf);
        WASM_VECTOR_LEN = buf.length;
        return ptr;
    }

    let len = arg.length;
    let ptr = malloc(len, 1) >>> 0;

    const mem = getUint8ArrayMemory0();

    let offset = 0;

    for (; offset < len; offset++) {
        const code = arg.charCodeAt(offset);
        if (code > 0x7F) break;
        mem[ptr + offset] = code;
    }
    if (offset !== len) {
        if (offset !== 0) {
            arg = arg.slice(offset);
        }
        ptr = realloc(ptr, len, len = offset + arg.length * 3, 1) >>> 0;
        const view = getUint8ArrayMemory0().subarray(ptr + offset, ptr + len);
        const ret = cachedTextEncoder.encodeInto(arg, view);

        offset += ret.written;
        ptr = realloc(ptr, len, offset, 1) >>> 0;
    }

    WASM_VECTOR_LEN = offset;
    return ptr;
}

function takeFromExternrefTable0(idx) {
    const value = wasm.__wbindgen_externrefs.get(idx);
    wasm.__externref_table_dealloc(idx);
    return value;
}

let cachedTextDecoder = new TextDecoder('utf-8', { ignoreBOM: true });
cachedTextDecoder.decode();
const MAX_SAFARI_DECODE_BYTES = 2146435072;
let numBytesDecoded = 0;
function decodeText(bytes) {
    numBytesDecoded += bytes.length;
    if (numBytesDecoded >= MAX_SAFARI_DECODE_BYTES) {
        cachedTextDecoder = new TextDecoder('utf-8', { ignoreBOM: true });
        cachedTextDecoder.decode();
        numBytesDecoded = bytes.length;
    }
    return cachedTextDecoder.decode(bytes);
}

const cachedTextEncoder = new TextEncoder();

if (!('encodeInto' in cachedTextEncoder)) {
    cachedTextEncoder.encodeInto = function (arg, view) {
        const buf = cachedTextEncoder.encode(arg);
        view.set(buf);
        return {
            read: arg.length,
            written: buf.length
        };
    };
}

let WASM_VECTOR_LEN = 0;

let wasmModule, wasmInstance, wasm;
function __wbg_finalize_init(instance, module) {
    wasmInstance = instance;
    wasm = instance.exports;
    wasmModule = module;
    cachedFloat32ArrayMemory0 = null;
    cachedUint32ArrayMemory0 = null;
    cachedUint8ArrayMemory0 = null;
    wasm.__wbindgen_start();
    return wasm;
}

async function __wbg_load(module, imports) {
    if (typeof Response === 'function' && module instanceof Response) {
        if (!module.ok) {
            throw new Error(`failed to fetch Wasm: ${module.status} ${module.statusText} fetching '${module.url}'`);
        }

        if (typeof WebAssembly.instantiateStreaming === 'function') {
            try {
                return await WebAssembly.instantiateStreaming(module, imports);
            } catch (e) {
                const validResponse = expectedResponseType(module.type);

                if (validResponse && module.headers.get('Content-Type') !== 'application/wasm') {
                    console.warn("`WebAssembly.instantiateStreaming` failed because your server does not serve Wasm with `application/wasm` MIME type. Falling back to `WebAssembly.instantiate` which is slower. Original error:\n", e);

                } else { throw e; }
            }
        }

        const bytes = await module.arrayBuffer();
        return await WebAssembly.instantiate(bytes, imports);
    } else {
        const instance = await WebAssembly.instantiate(module, imports);

        if (instance instanceof WebAssembly.Instance) {
            return { instance, module };
        } else {
            return instance;
        }
    }

    function expectedResponseType(type) {
        switch (type) {
            case 'basic': case 'cors': case 'default': return true;
        }
        return false;
    }
}

function initSync(module) {
    if (wasm !== undefined) return wasm;


    if (module !== undefined) {
        if (Object.getPrototypeOf(module) === Object.prototype) {
            ({module} = module)
        } else {
            console.warn('using deprecated parameters for `initSync()`; pass a single object instead')
        }
    }

    const imports = __wbg_get_imports();
    if (!(module instanceof WebAssembly.Module)) {
        module = new WebAssembly.Module(module);
    }
    const instance = new WebAssembly.Instance(module, imports);
    return __wbg_finalize_init(instance, module);
}

let __wbg_init_promise;
async function __wbg_init(module_or_path) {
    if (wasm !== undefined) return wasm;
    if (__wbg_init_promise === undefined) {
        __wbg_init_promise = __wbg_init_once(module_or_path);
        __wbg_init_promise.catch(() => { __wbg_init_promise = undefined; });
    }
    return __wbg_init_promise;
}

async function __wbg_init_once(module_or_path) {

    if (module_or_path !== undefined) {
        if (Object.getPrototypeOf(module_or_path) === Object.prototype) {
            ({module_or_path} = module_or_path)
        } else {
            console.warn('using deprecated parameters for the initialization function; pass a single object instead')
        }
    }

    if (module_or_path === undefined) {
        module_or_path = new URL('relief_wasm_bg.wasm', import.meta.url);
    }
    const imports = __wbg_get_imports();

    if (typeof module_or_path === 'string' || (typeof Request === 'function' && module_or_path instanceof Request) || (typeof URL === 'function' && module_or_path instanceof URL)) {
        module_or_path = fetch(module_or_path);
    }

    const { instance, module } = await __wbg_load(await module_or_path, imports);

    return __wbg_finalize_init(instance, module);
}

export { initSync, __wbg_init as default };
