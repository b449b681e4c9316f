-- mipmb.lua: Wireshark post-dissector for Piciorgros MIP over Modbus/TCP (mip-logger)
--
-- Labels the PLC <-> modem link of a TRM-810 (outstation) or MDP-810 (central) in MIP mode:
-- the registers of the Piciorgros note "SPS-Kopplung über MODBUS/IP im Zeitschlitzfunk"
-- (section 3.1 MDP-810, 3.2 TRM-810: register maps; 3.1.1 / 3.2.1, pages 12 and 14: the
-- read-status bits, bit 0 "Neue Lesedaten" set when a new block arrived and cleared by any
-- read of the read area) and the logger protocol's counters of its section 2.1 (record
-- counter 1, 2, ... 16#FFFF last; 0 before anything was received; the acknowledgement mirrors
-- the last record received) and 2.2 (bidirectional: two counters). Wireshark's own
-- Modbus/TCP dissector (mbtcp, modbus) cuts the TCP stream
-- into Modbus frames; this script reads each frame's bytes and labels what it knows.
--
-- Install: copy this file to ~/.local/lib/wireshark/plugins/ (Wireshark's personal Lua
-- plugins folder; `tshark -G folders` shows it), or load it for one run:
--   tshark -X lua_script:mipmb.lua -r capture.pcap
-- Documentation: docs/wireshark.md of mip-logger.
--
-- Registers it does not know are left alone; a malformed frame is skipped, never an error.

local VERSION = "1.1"

local p = Proto("mipmb", "Piciorgros MIP over Modbus")

-- preferences ---------------------------------------------------------------------------
p.prefs.ports = Pref.range("Modbus/TCP ports",
    "502,15020-15040",
    "TCP ports of the modems (Modbus/TCP servers): 502 is the Modbus default, 15020 the " ..
    "emulator's MDP-810 and 15021.. its TRM-810s. Modbus/TCP is decoded on these ports.", 65535)
p.prefs.trm_write = Pref.uint("TRM-810 first write register", 2001,
    "note 3.2: write data 2001-2148, 2000 = number of write registers")
p.prefs.trm_status = Pref.uint("TRM-810 read-status register", 2198,
    "note 3.2: read status 2198, 2199 number received, read data from 2200")
p.prefs.mdp_write = Pref.uint("MDP-810 first write register", 10,
    "note 3.1: write data from 10, 9 = number of write registers, 0..2 and 4 below it")
p.prefs.mdp_status = Pref.uint("MDP-810 read-status register (copy)", 198,
    "note 3.1: 198 copy of the read status, 199 number received, read data from 200")
p.prefs.one_based = Pref.bool("Modem counts from 1", false,
    "The note's numbers are 1-based register numbers: the address on the wire is the " ..
    "number - 1 (off: the numbers are the 0-based addresses on the wire)")
p.prefs.bidi = Pref.bool("Bidirectional layout (note 2.2)", false,
    "two counters in every block: register 0 for the outstation's records, " ..
    "register 1 for the central's records")

-- fields ----------------------------------------------------------------------------------
-- Counters are plain numbers (a filter `mipmb.record == 3` works); the two values the note
-- names get their name appended to the item (note 2.1): 0 and 16#FFFF.
local COUNTER_NAME = { [0] = "start: no record received yet", [65535] = "16#FFFF: the last record" }
local F = {
    device = ProtoField.string("mipmb.device", "Modem"),
    station = ProtoField.uint8("mipmb.station", "Station (MDP unit id)"),
    kind = ProtoField.string("mipmb.kind", "Access"),
    hop = ProtoField.string("mipmb.hop", "Direction"),
    no_new = ProtoField.string("mipmb.no_new_data", "Read without new data"),
    old = ProtoField.uint16("mipmb.old_counter", "Counter still in the read area (read before)"),
    reg = ProtoField.string("mipmb.register", "Register"),
    status = ProtoField.uint16("mipmb.read_status", "Read status", base.HEX),
    st_new = ProtoField.bool("mipmb.read_status.new_data", "Bit 0 new read data", 16, nil, 0x0001),
    st_wait = ProtoField.bool("mipmb.read_status.write_waiting", "Bit 1 write data waiting", 16, nil, 0x0002),
    st_unconf = ProtoField.bool("mipmb.read_status.write_unconfirmed", "Bit 4 write data unconfirmed", 16, nil, 0x0010),
    rcount = ProtoField.uint16("mipmb.read_count", "Number of registers received"),
    wcount = ProtoField.uint16("mipmb.write_count", "Number of write registers"),
    field_st = ProtoField.uint8("mipmb.field.station_hears", "Station hears the MDP at -dBm"),
    field_mdp = ProtoField.uint8("mipmb.field.mdp_hears", "MDP hears the station at -dBm"),
    ststat = ProtoField.uint16("mipmb.station_status", "Station status", base.HEX),
    record = ProtoField.uint16("mipmb.record", "Record counter", base.DEC),
    ack = ProtoField.uint16("mipmb.ack", "Acknowledgement counter", base.DEC),
    len = ProtoField.uint16("mipmb.len", "Block length (registers)"),
}
p.fields = {}
for _, f in pairs(F) do table.insert(p.fields, f) end

local E = {
    never_sent = ProtoExpert.new("mipmb.ack_never_sent", "Acknowledgement of a record never sent",
        expert.group.SEQUENCE, expert.severity.WARN),
    backwards = ProtoExpert.new("mipmb.counter_backwards", "Counter went backwards",
        expert.group.SEQUENCE, expert.severity.WARN),
    skipped = ProtoExpert.new("mipmb.record_skipped", "Record counter skipped a number",
        expert.group.SEQUENCE, expert.severity.WARN),
}
p.experts = { E.never_sent, E.backwards, E.skipped }

-- fields of other dissectors --------------------------------------------------------------
local fi_mbtcp = Field.new("mbtcp")
local fi_srcport = Field.new("tcp.srcport")
local fi_dstport = Field.new("tcp.dstport")
local fi_stream = Field.new("tcp.stream")

-- state (built on the first pass, in frame order) -----------------------------------------
local requests, links, verdicts, portset, last_frame

-- Frames are judged once, in order: a frame above the last one judged is new, the others
-- (Wireshark's GUI revisiting a frame, tshark's second pass) show what was judged then. Not
-- pinfo.visited: tshark -2 runs the init routine between its passes, which empties the state.
local function reset()
    requests = {}   -- "stream:tid" -> {fc, ra, rq}
    links = {}      -- "modem address:port[:unit]/stream" -> counters of one link
    verdicts = {}   -- "frame:pdu:reg" -> expert key
    last_frame = 0
end
reset()
p.init = reset

local function in_ports(port)
    if not port then return false end
    local ok, hit = pcall(function() return portset[port] end)
    return ok and hit
end

local function parse_ports(s)
    local set = {}
    for part in string.gmatch(s or "", "[^,%s]+") do
        local a, b = string.match(part, "^(%d+)-(%d+)$")
        if a then
            for v = tonumber(a), math.min(tonumber(b), 65535) do set[v] = true end
        elseif tonumber(part) then
            set[tonumber(part)] = true
        end
    end
    return set
end

local registered = {}
local function register_ports()
    portset = parse_ports(tostring(p.prefs.ports))
    local mbtcp = Dissector.get("mbtcp")
    local tcp = DissectorTable.get("tcp.port")
    if not (mbtcp and tcp) then return end
    for port in pairs(registered) do
        if not portset[port] and port ~= 502 then pcall(function() tcp:remove(port, mbtcp) end) end
    end
    registered = {}
    for port in pairs(portset) do
        pcall(function() tcp:add(port, mbtcp) end)
        registered[port] = true
    end
end
p.prefs_changed = register_ports
register_ports()

-- the register map ------------------------------------------------------------------------
-- Which modem a request addresses: by its address (TRM 2000-2347 and MDP 0-347 do not overlap).
local function map()
    local off = p.prefs.one_based and 1 or 0
    local tw, ts = p.prefs.trm_write - off, p.prefs.trm_status - off
    local mw, ms = p.prefs.mdp_write - off, p.prefs.mdp_status - off
    return {
        trm = { wcount = tw - 1, write = tw, status = ts, rcount = ts + 1, read = ts + 2 },
        mdp = { field = mw - 10, ststat = mw - 9, status2 = mw - 8, rcount4 = mw - 6,
                wcount = mw - 1, write = mw, status = ms, rcount = ms + 1, read = ms + 2 },
    }
end

local function device_of(m, addr)
    if addr >= m.trm.wcount and addr < m.trm.read + 148 then return "trm" end
    if addr >= m.mdp.field and addr < m.mdp.read + 148 then return "mdp" end
    return nil
end

-- What register 0 / 1 of a block carries, and whose records that counter counts. Written at
-- the TRM and read at the MDP: the outstation's block, which the radio carries
-- outstation->central (its record counter; bidirectional also its acknowledgement of the
-- central's records); the other way round the central's block, carried central->outstation.
local function block_slots(outstation_block)
    if p.prefs.bidi then
        if outstation_block then
            return { { "record", "outstation" }, { "ack", "central" } }
        end
        return { { "ack", "outstation" }, { "record", "central" } }
    end
    if outstation_block then return { { "record", "outstation" } } end
    return { { "ack", "outstation" } }
end

local OTHER = { outstation = "central", central = "outstation" }

-- The counter's meaning in words a field engineer reads in the packet details: whose record
-- (or whose acknowledgement of whose records), with the names of note 2.1 for 0 and 16#FFFF,
-- and the way its block goes over the radio.
local function counter_text(what, v, owner)
    local text
    if what == "record" then
        if v == 0 then text = COUNTER_NAME[0] .. " (0 is no record number, note 2.1)"
        elseif v == 65535 then text = COUNTER_NAME[65535] .. " of the " .. owner
        else text = "the " .. owner .. "'s record " .. v end
    else
        local by = OTHER[owner]
        if v == 0 then text = COUNTER_NAME[0] .. " by the " .. by .. " from the " .. owner
        elseif v == 65535 then text = "the " .. by .. " acknowledges the " .. owner ..
            "'s last record (16#FFFF)"
        else text = "the " .. by .. " acknowledges the " .. owner .. "'s record " .. v end
    end
    local sender = what == "record" and owner or OTHER[owner]
    return text .. "; radio " .. sender .. "->" .. OTHER[sender]
end

-- The checks: per link (a TRM's address and port, or an MDP's and the unit id) and stream.
-- sent: record numbers the sender wrote (or the receiver read as new data) since the
-- current transfer began; judged only once the capture has seen one.
local function link(key, stream)
    local k = key .. "/" .. stream
    local l = links[k]
    if not l then
        l = { last = {}, max = nil, has_ffff = false }
        links[k] = l
    end
    return l
end

local function check_record(l, v)
    local prev = l.last.record
    local verdict
    if prev and v ~= prev and v ~= 0 and v ~= 1 and prev ~= 65535 and v ~= 65535 then
        if v < prev then verdict = "backwards"
        elseif v > prev + 1 then verdict = "skipped" end
    end
    l.last.record = v
    if v == 1 then l.max, l.has_ffff = 1, false
    elseif v == 65535 then l.has_ffff = true
    elseif v ~= 0 and (l.max == nil or v > l.max) then l.max = v end
    return verdict
end

local function check_ack(l, v, written)
    local verdict
    if written then
        local prev = l.last.ack
        if prev and v < prev and v ~= 0 and v ~= 1 and prev ~= 65535 then verdict = "backwards" end
        l.last.ack = v
    end
    if not verdict and l.max and v ~= 0 then
        if v == 65535 then
            if not l.has_ffff and l.max >= 2 then verdict = "never_sent" end
        elseif v > l.max then
            verdict = "never_sent"
        end
    end
    return verdict
end

-- dissection ------------------------------------------------------------------------------
local function u16(r, o) return r:range(o, 2):uint() end

local info = {}   -- the Info column's additions of the frame being dissected

local function add_counter(sub, rng, what, v, owner, vkey, verdict)
    table.insert(info, (what == "record" and "record " or "ack ") .. (v == 65535 and "16#FFFF" or v))
    local item = sub:add(what == "record" and F.record or F.ack, rng, v)
    item:append_text(" (" .. counter_text(what, v, owner) .. ")")
    if verdict then
        local e = E[verdict]
        local msg = verdict == "never_sent" and
            ("acknowledges " .. v .. ", a record not sent in this transfer") or
            verdict == "backwards" and ("counter went back to " .. v) or
            ("record " .. v .. " skips a number")
        item:add_proto_expert_info(e, msg)
    end
end

-- One block's counters (registers at rng, the block's first register), with the checks. A
-- block read without new data (status bit 0 clear) is the one read before: its counters are
-- shown as such (mipmb.old_counter), never as a record or an acknowledgement that arrived.
local function counters(sub, rng, n, dev, unit_key, written, fresh, frame_key, first_pass)
    local outstation_block = (dev == "trm") == written
    local slots = block_slots(outstation_block)
    if not written and not fresh then
        sub:add(F.no_new, rng:range(0, math.min(n, #slots) * 2),
            "status bit 0 clear: nothing arrived since the last read (note 3.1.1 / 3.2.1)")
        for i = 1, math.min(n, #slots) do
            sub:add(F.old, rng:range((i - 1) * 2, 2)):append_text(
                " (" .. slots[i][1] .. " counter of the block read before)")
        end
        table.insert(info, "read, no new data")
        return
    end
    for i, slot in ipairs(slots) do
        if i <= n then
            local what, stream = slot[1], slot[2]
            local v = u16(rng, (i - 1) * 2)
            local vkey = frame_key .. ":" .. i
            if first_pass then
                local l = link(unit_key, stream)
                local verdict
                if what == "record" and (written or fresh) then
                    verdict = check_record(l, v)
                    if not written then verdict = nil end  -- read: the sender's business
                elseif what == "ack" and (written or fresh) then
                    verdict = check_ack(l, v, written)
                end
                verdicts[vkey] = verdict or false
            end
            add_counter(sub, rng:range((i - 1) * 2, 2), what, v, stream, vkey, verdicts[vkey] or nil)
        end
    end
end

local function read_regs(sub, data, ra, rq, m, dev, key, frame_key, first_pass)
    local d = m[dev]
    local fresh = nil
    local function at(addr)
        local i = addr - ra
        if i >= 0 and i < rq and (i + 1) * 2 <= data:len() then return data:range(i * 2, 2) end
        return nil
    end
    local function status_item(r, label)
        local t = sub:add(F.status, r)
        t:prepend_text(label .. " ")
        t:add(F.st_new, r)
        t:add(F.st_wait, r)
        t:add(F.st_unconf, r)
        return r:uint()
    end
    local r = at(d.status)
    if r then fresh = status_item(r, tostring(d.status)) % 2 == 1 end
    if dev == "mdp" then
        r = at(d.status2)
        if r then
            local s = status_item(r, tostring(d.status2))
            if fresh == nil then fresh = s % 2 == 1 end
        end
        r = at(d.field)
        if r then
            sub:add(F.field_st, r:range(0, 1))
            sub:add(F.field_mdp, r:range(1, 1))
        end
        r = at(d.ststat)
        if r then sub:add(F.ststat, r):append_text(" (emulator-defined bits: docs/wireshark.md)") end
        r = at(d.rcount4)
        if r then sub:add(F.rcount, r) end
    end
    r = at(d.rcount)
    if r then sub:add(F.rcount, r) end
    r = at(d.wcount)
    if r then sub:add(F.wcount, r) end
    -- the block received: its counters. Without the status in the same read, a read of the
    -- data is taken as new (the block judges the same way on its first read).
    local i = d.read - ra
    if i >= 0 and i < rq and (i + 1) * 2 <= data:len() then
        local n = math.min(rq - i, math.floor(data:len() / 2) - i)
        counters(sub, data:range(i * 2), n, dev, key, false, fresh ~= false, frame_key, first_pass)
    end
end

local function dissect_pdu(rng, pinfo, tree, idx, first_pass, sport, dport, tcpstream)
    if rng:len() < 8 then return end
    local tid = u16(rng, 0)
    local unit = rng:range(6, 1):uint()
    local fc = rng:range(7, 1):uint()
    local pdu = rng:range(8)
    local is_request = in_ports(dport) and not in_ports(sport)
    local is_response = in_ports(sport) and not in_ports(dport)
    if not (is_request or is_response) then return end
    local m = map()
    local rkey = tcpstream .. ":" .. tid
    local frame_key = pinfo.number .. ":" .. idx
    local ra, rq, wa, wq, wdata
    if is_request then
        local n = pdu:len()
        if (fc == 3 or fc == 4) and n >= 4 then
            ra, rq = u16(pdu, 0), u16(pdu, 2)
        elseif fc == 16 and n >= 5 then
            wa, wq = u16(pdu, 0), u16(pdu, 2)
            wdata = pdu:range(5)
        elseif fc == 23 and n >= 9 then
            ra, rq, wa, wq = u16(pdu, 0), u16(pdu, 2), u16(pdu, 4), u16(pdu, 6)
            wdata = n > 9 and pdu:range(9) or nil
        elseif fc == 6 and n >= 4 then
            wa, wq, wdata = u16(pdu, 0), 1, pdu:range(2, 2)
        else
            return
        end
        if first_pass and ra then requests[rkey] = { fc = fc, ra = ra, rq = rq } end
    else
        if fc >= 0x80 then return end
        local q = requests[rkey .. "@" .. frame_key] or requests[rkey]
        if first_pass then requests[rkey .. "@" .. frame_key] = q end
        if not q or q.fc ~= fc or pdu:len() < 1 then return end
        ra, rq = q.ra, q.rq
    end
    local dev = device_of(m, ra or wa)
    if not dev then return end
    local sub = tree:add(p, rng)
    sub:add(F.device, dev == "trm" and "TRM-810 (outstation)" or "MDP-810 (central)")
    -- the link: the modem's address and port (a PLC may open a new connection for each request)
    local key = is_request and (tostring(pinfo.dst) .. ":" .. tostring(dport))
        or (tostring(pinfo.src) .. ":" .. tostring(sport))
    if dev == "mdp" then
        sub:add(F.station, rng:range(6, 1))
        key = key .. ":" .. unit
    end
    -- the Modbus hop: a request goes from the PLC to its modem, a response back
    local modem = dev == "trm" and "TRM-810" or "MDP-810"
    local plc = dev == "trm" and "outstation PLC" or "central PLC"
    local hop = is_request and (plc .. " -> " .. modem) or (modem .. " -> " .. plc)
    sub:add(F.hop, hop)
    sub:append_text(": " .. (dev == "trm" and "TRM-810" or "MDP-810, station " .. unit) ..
        ", " .. hop)
    if wa and wdata then
        sub:add(F.kind, fc == 23 and "write and read request" or "write request")
        if wa == m[dev].write and wq and fc ~= 6 then
            sub:add(F.len, pdu:range(2, 2), wq):append_text(" (the block written)")
            local n = math.min(wq, math.floor(wdata:len() / 2))
            if n >= 1 then counters(sub, wdata, n, dev, key, true, false, frame_key .. "w", first_pass) end
        end
    end
    if ra and is_response then
        sub:add(F.kind, "read response")
        local data = pdu:len() > 1 and pdu:range(1) or nil
        if data then read_regs(sub, data, ra, rq, m, dev, key, frame_key .. "r", first_pass) end
    elseif ra and fc ~= 23 then
        sub:add(F.kind, "read request")
    end
end

function p.dissector(tvb, pinfo, tree)
    local ok, err = pcall(function()
        local pdus = { fi_mbtcp() }
        if #pdus == 0 then return end
        local sport = fi_srcport() and fi_srcport().value
        local dport = fi_dstport() and fi_dstport().value
        local stream = fi_stream() and fi_stream().value or 0
        local first_pass = pinfo.number > last_frame
        if first_pass then last_frame = pinfo.number end
        info = {}
        for i, fi in ipairs(pdus) do
            local rng = fi.range
            if rng then dissect_pdu(rng, pinfo, tree, i, first_pass, sport, dport, stream) end
        end
        if #info > 0 then pinfo.cols.info:append(" [MIP " .. table.concat(info, ", ") .. "]") end
    end)
    if not ok and os.getenv("MIPMB_DEBUG") then
        io.stderr:write("mipmb: frame " .. pinfo.number .. ": " .. tostring(err) .. "\n")
    end
end

register_postdissector(p, true)
