-- A bandada swarm database at schema version 1 (the seed data of that release),
-- frozen: tests/swarm_node/database/test_migrations.py migrates it to the latest.
PRAGMA application_id = 1111576132;
PRAGMA user_version = 1;
BEGIN TRANSACTION;
CREATE TABLE comms_systems (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    kind TEXT NOT NULL CHECK (kind IN ('xtend900', 'microhard', 'wifi', 'ethernet', 'lte', 'other')),
    address TEXT NOT NULL DEFAULT '',
    system_id INTEGER REFERENCES systems(id) ON DELETE CASCADE,
    description TEXT NOT NULL DEFAULT ''
) STRICT;
INSERT INTO "comms_systems" VALUES(1,'XTend ALB-01','xtend900','/dev/xtend',1,'900 MHz mesh radio (XTend 1 W)');
INSERT INTO "comms_systems" VALUES(2,'Microhard ALB-01','microhard','192.168.168.11',1,'payload radio modem');
INSERT INTO "comms_systems" VALUES(3,'XTend ALB-02','xtend900','/dev/xtend',2,'900 MHz mesh radio (XTend 1 W)');
INSERT INTO "comms_systems" VALUES(4,'Microhard ALB-02','microhard','192.168.168.12',2,'payload radio modem');
INSERT INTO "comms_systems" VALUES(5,'XTend ALB-03','xtend900','/dev/xtend',3,'900 MHz mesh radio (XTend 1 W)');
INSERT INTO "comms_systems" VALUES(6,'Microhard ALB-03','microhard','192.168.168.13',3,'payload radio modem');
INSERT INTO "comms_systems" VALUES(7,'XTend ALB-04','xtend900','/dev/xtend',4,'900 MHz mesh radio (XTend 1 W)');
INSERT INTO "comms_systems" VALUES(8,'Microhard ALB-04','microhard','192.168.168.14',4,'payload radio modem');
INSERT INTO "comms_systems" VALUES(9,'XTend ALB-05','xtend900','/dev/xtend',5,'900 MHz mesh radio (XTend 1 W)');
INSERT INTO "comms_systems" VALUES(10,'Microhard ALB-05','microhard','192.168.168.15',5,'payload radio modem');
INSERT INTO "comms_systems" VALUES(11,'XTend ALB-06','xtend900','/dev/xtend',6,'900 MHz mesh radio (XTend 1 W)');
INSERT INTO "comms_systems" VALUES(12,'Microhard ALB-06','microhard','192.168.168.16',6,'payload radio modem');
INSERT INTO "comms_systems" VALUES(13,'XTend QUAD-01','xtend900','/dev/xtend',7,'900 MHz mesh radio (XTend 1 W)');
INSERT INTO "comms_systems" VALUES(14,'XTend QUAD-02','xtend900','/dev/xtend',8,'900 MHz mesh radio (XTend 1 W)');
INSERT INTO "comms_systems" VALUES(15,'XTend QUAD-03','xtend900','/dev/xtend',9,'900 MHz mesh radio (XTend 1 W)');
INSERT INTO "comms_systems" VALUES(16,'XTend ROVER-01','xtend900','/dev/xtend',10,'900 MHz mesh radio (XTend 1 W)');
INSERT INTO "comms_systems" VALUES(17,'XTend ROVER-02','xtend900','/dev/xtend',11,'900 MHz mesh radio (XTend 1 W)');
INSERT INTO "comms_systems" VALUES(18,'XTend BOAT-01','xtend900','/dev/xtend',12,'900 MHz mesh radio (XTend 1 W)');
INSERT INTO "comms_systems" VALUES(19,'XTend BOAT-02','xtend900','/dev/xtend',13,'900 MHz mesh radio (XTend 1 W)');
INSERT INTO "comms_systems" VALUES(20,'XTend GCS-01','xtend900','/dev/xtend',900,'900 MHz mesh radio (XTend 1 W)');
CREATE TABLE computer_layouts (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    board TEXT NOT NULL CHECK (length(board) >= 1),
    cpu TEXT NOT NULL DEFAULT '',
    ram_mb INTEGER NOT NULL DEFAULT 0 CHECK (ram_mb BETWEEN 0 AND 16777216),
    os TEXT NOT NULL DEFAULT '',
    description TEXT NOT NULL DEFAULT ''
) STRICT;
INSERT INTO "computer_layouts" VALUES(1,'Raspberry Pi 4','Raspberry Pi 4 Model B','Cortex-A72 4 x 1.5 GHz',4096,'Raspberry Pi OS 12','');
INSERT INTO "computer_layouts" VALUES(2,'Jetson Orin Nano','NVIDIA Jetson Orin Nano 8GB','Cortex-A78AE 6 x 1.5 GHz',8192,'Ubuntu 22.04 (JetPack 6)','');
INSERT INTO "computer_layouts" VALUES(3,'Ground station laptop','Lenovo Legion 5 16IRX8','Intel Core i7-13700HX',32768,'Ubuntu 24.04','');
CREATE TABLE corrections (
    id INTEGER PRIMARY KEY,
    bug_id TEXT NOT NULL UNIQUE CHECK (length(bug_id) BETWEEN 1 AND 48 AND bug_id = trim(bug_id)),
    module TEXT NOT NULL CHECK (length(module) >= 1),
    description TEXT NOT NULL CHECK (length(description) >= 1),
    criticality TEXT NOT NULL CHECK (criticality IN ('low', 'medium', 'high', 'critical'))
) STRICT;
CREATE TABLE gimbal_axis_params (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    axis TEXT NOT NULL CHECK (axis IN ('roll', 'tilt', 'pan')),
    motor_id INTEGER REFERENCES motors(id),
    pid_id INTEGER REFERENCES pid_controllers(id),
    min_angle_deg REAL NOT NULL CHECK (min_angle_deg BETWEEN -360 AND 360),
    max_angle_deg REAL NOT NULL CHECK (max_angle_deg BETWEEN -360 AND 360),
    max_rate_deg_s REAL NOT NULL DEFAULT 0 CHECK (max_rate_deg_s BETWEEN 0 AND 10000),
    CONSTRAINT axis_range_ordered CHECK (min_angle_deg < max_angle_deg)
) STRICT;
INSERT INTO "gimbal_axis_params" VALUES(1,'roll +-45','roll',1,1,-45.0,45.0,180.0);
INSERT INTO "gimbal_axis_params" VALUES(2,'tilt -90..+30','tilt',1,2,-90.0,30.0,120.0);
INSERT INTO "gimbal_axis_params" VALUES(3,'pan 360','pan',1,3,-180.0,180.0,180.0);
CREATE TABLE gimbal_configs (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    baud_rate INTEGER NOT NULL CHECK (baud_rate BETWEEN 1 AND 100000000),
    period_ms REAL NOT NULL CHECK (period_ms > 0 AND period_ms <= 1e6),
    pan_axis_id INTEGER REFERENCES gimbal_axis_params(id),
    tilt_axis_id INTEGER REFERENCES gimbal_axis_params(id),
    roll_axis_id INTEGER REFERENCES gimbal_axis_params(id)
) STRICT;
INSERT INTO "gimbal_configs" VALUES(1,'2-axis roll/tilt',115200,20.0,NULL,2,1);
INSERT INTO "gimbal_configs" VALUES(2,'3-axis',115200,20.0,3,2,1);
CREATE TABLE mission_params (
    mission_id INTEGER NOT NULL REFERENCES missions(id) ON DELETE CASCADE,
    name TEXT NOT NULL CHECK (length(name) BETWEEN 1 AND 64 AND name = trim(name)),
    value REAL NOT NULL CHECK (value BETWEEN -1e12 AND 1e12),
    unit TEXT NOT NULL DEFAULT '',
    description TEXT NOT NULL DEFAULT '',
    PRIMARY KEY (mission_id, name)
) STRICT;
INSERT INTO "mission_params" VALUES(1,'altitude_rel_m',100.0,'m','');
INSERT INTO "mission_params" VALUES(1,'side_overlap',0.7,'','fraction of the camera footprint');
INSERT INTO "mission_params" VALUES(2,'altitude_rel_m',100.0,'m','');
INSERT INTO "mission_params" VALUES(2,'radius_m',150.0,'m','');
INSERT INTO "mission_params" VALUES(2,'altitude_step_m',10.0,'m','vertical separation between vehicles');
INSERT INTO "mission_params" VALUES(3,'altitude_rel_m',100.0,'m','');
INSERT INTO "mission_params" VALUES(3,'altitude_step_m',10.0,'m','');
INSERT INTO "mission_params" VALUES(4,'altitude_rel_m',100.0,'m','');
INSERT INTO "mission_params" VALUES(5,'altitude_rel_m',100.0,'m','');
INSERT INTO "mission_params" VALUES(5,'duration_s',60.0,'s','hold at each point');
INSERT INTO "mission_params" VALUES(6,'separation_s',30.0,'s','time between landings');
INSERT INTO "mission_params" VALUES(7,'altitude_step_m',20.0,'m','');
CREATE TABLE missions (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    mission_type INTEGER NOT NULL UNIQUE CHECK (mission_type BETWEEN 1 AND 255),
    description TEXT NOT NULL DEFAULT ''
) STRICT;
INSERT INTO "missions" VALUES(1,'area',1,'cover a polygon with camera lanes');
INSERT INTO "missions" VALUES(2,'target',2,'orbit or hover around a point');
INSERT INTO "missions" VALUES(3,'perimeter',3,'patrol a closed boundary');
INSERT INTO "missions" VALUES(4,'route',4,'follow a polyline');
INSERT INTO "missions" VALUES(5,'objective',5,'visit points');
INSERT INTO "missions" VALUES(6,'autoland',6,'land one after another');
INSERT INTO "missions" VALUES(7,'MUM-T',7,'accompany a manned lead');
CREATE TABLE module_params (
    module_id INTEGER NOT NULL REFERENCES modules(id) ON DELETE CASCADE,
    name TEXT NOT NULL CHECK (length(name) BETWEEN 1 AND 64 AND name = trim(name)),
    value REAL NOT NULL CHECK (value BETWEEN -1e12 AND 1e12),
    unit TEXT NOT NULL DEFAULT '',
    description TEXT NOT NULL DEFAULT '',
    PRIMARY KEY (module_id, name)
) STRICT;
INSERT INTO "module_params" VALUES(1,'risk_distance_m',40.0,'m','');
INSERT INTO "module_params" VALUES(1,'danger_distance_m',10.0,'m','');
INSERT INTO "module_params" VALUES(1,'near_collision_m',5.0,'m','');
INSERT INTO "module_params" VALUES(1,'ttc_threshold_s',20.0,'s','assumption');
INSERT INTO "module_params" VALUES(1,'climb_step_m',15.0,'m','assumption');
INSERT INTO "module_params" VALUES(1,'hysteresis_s',5.0,'s','assumption');
INSERT INTO "module_params" VALUES(2,'risk_distance_m',40.0,'m','');
INSERT INTO "module_params" VALUES(2,'danger_distance_m',10.0,'m','');
INSERT INTO "module_params" VALUES(2,'near_collision_m',5.0,'m','');
INSERT INTO "module_params" VALUES(2,'ttc_threshold_s',10.0,'s','assumption');
INSERT INTO "module_params" VALUES(2,'climb_step_m',5.0,'m','assumption');
INSERT INTO "module_params" VALUES(2,'hysteresis_s',3.0,'s','assumption');
INSERT INTO "module_params" VALUES(3,'weight_payload',0.6,'','');
INSERT INTO "module_params" VALUES(3,'weight_time',0.2,'','');
INSERT INTO "module_params" VALUES(3,'weight_battery',0.3,'','');
INSERT INTO "module_params" VALUES(3,'time_scale_per_s',0.01,'1/s','time score = atanh(t x scale)');
CREATE TABLE modules (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    subtype_id INTEGER REFERENCES system_subtypes(id),
    description TEXT NOT NULL DEFAULT ''
) STRICT;
INSERT INTO "modules" VALUES(1,'collision avoidance (fixed-wing)',1,'TTC extrapolation, upward-only altitude manoeuvre (also VTOL)');
INSERT INTO "modules" VALUES(2,'collision avoidance (multirotor)',3,'TTC extrapolation, altitude manoeuvre');
INSERT INTO "modules" VALUES(3,'voting',NULL,'QUANTITY missions: score = 1 - sum(w v) (paper section 2.3.6)');
CREATE TABLE motors (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    kind TEXT NOT NULL CHECK (kind IN ('servo', 'brushless', 'stepper', 'dc')),
    description TEXT NOT NULL DEFAULT ''
) STRICT;
INSERT INTO "motors" VALUES(1,'gimbal brushless','brushless','');
INSERT INTO "motors" VALUES(2,'gimbal servo','servo','');
CREATE TABLE payload_layouts (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    model_id INTEGER NOT NULL REFERENCES payload_models(id),
    gimbal_id INTEGER REFERENCES gimbal_configs(id),
    sensor_id INTEGER REFERENCES sensors(id),
    description TEXT NOT NULL DEFAULT ''
) STRICT;
INSERT INTO "payload_layouts" VALUES(1,'EO 1.5 Mpx 2-axis',1,1,1,'');
INSERT INTO "payload_layouts" VALUES(2,'EO 12 Mpx 3-axis',2,2,2,'');
INSERT INTO "payload_layouts" VALUES(3,'Thermal 640 3-axis',3,2,3,'');
INSERT INTO "payload_layouts" VALUES(4,'SDR receiver',4,NULL,4,'');
CREATE TABLE payload_models (
    id INTEGER PRIMARY KEY,
    subtype_id INTEGER NOT NULL REFERENCES payload_subtypes(id),
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    description TEXT NOT NULL DEFAULT ''
) STRICT;
INSERT INTO "payload_models" VALUES(1,1,'EO 1.5 Mpx 2-axis gimbal','the paper''s two-axis gyrostabilized 1.5 Mpx camera');
INSERT INTO "payload_models" VALUES(2,1,'EO 12 Mpx 3-axis gimbal','');
INSERT INTO "payload_models" VALUES(3,2,'Thermal 640 3-axis gimbal','');
INSERT INTO "payload_models" VALUES(4,3,'SDR receiver','');
INSERT INTO "payload_models" VALUES(5,4,'Acoustic array','');
CREATE TABLE payload_params (
    payload_id INTEGER NOT NULL REFERENCES payloads(id) ON DELETE CASCADE,
    name TEXT NOT NULL CHECK (length(name) BETWEEN 1 AND 64 AND name = trim(name)),
    value TEXT NOT NULL,
    PRIMARY KEY (payload_id, name)
) STRICT;
INSERT INTO "payload_params" VALUES(1,'interface','ethernet');
INSERT INTO "payload_params" VALUES(1,'protocol','RTSP');
INSERT INTO "payload_params" VALUES(2,'interface','ethernet');
INSERT INTO "payload_params" VALUES(2,'protocol','RTSP');
INSERT INTO "payload_params" VALUES(3,'interface','ethernet');
INSERT INTO "payload_params" VALUES(3,'protocol','RTSP');
INSERT INTO "payload_params" VALUES(4,'interface','ethernet');
INSERT INTO "payload_params" VALUES(4,'protocol','RTSP');
INSERT INTO "payload_params" VALUES(5,'interface','ethernet');
INSERT INTO "payload_params" VALUES(5,'protocol','RTSP');
INSERT INTO "payload_params" VALUES(6,'interface','ethernet');
INSERT INTO "payload_params" VALUES(6,'protocol','RTSP');
INSERT INTO "payload_params" VALUES(7,'interface','ethernet');
INSERT INTO "payload_params" VALUES(7,'protocol','RTSP');
INSERT INTO "payload_params" VALUES(8,'interface','ethernet');
INSERT INTO "payload_params" VALUES(8,'protocol','RTSP');
INSERT INTO "payload_params" VALUES(9,'interface','ethernet');
INSERT INTO "payload_params" VALUES(9,'protocol','RTSP');
INSERT INTO "payload_params" VALUES(10,'interface','usb');
INSERT INTO "payload_params" VALUES(10,'protocol','SoapySDR');
INSERT INTO "payload_params" VALUES(11,'interface','usb');
INSERT INTO "payload_params" VALUES(11,'protocol','SoapySDR');
INSERT INTO "payload_params" VALUES(12,'interface','ethernet');
INSERT INTO "payload_params" VALUES(12,'protocol','RTSP');
INSERT INTO "payload_params" VALUES(13,'interface','ethernet');
INSERT INTO "payload_params" VALUES(13,'protocol','RTSP');
CREATE TABLE payload_subtypes (
    id INTEGER PRIMARY KEY,
    type_id INTEGER NOT NULL REFERENCES payload_types(id),
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    description TEXT NOT NULL DEFAULT ''
) STRICT;
INSERT INTO "payload_subtypes" VALUES(1,1,'visible camera','');
INSERT INTO "payload_subtypes" VALUES(2,1,'thermal camera','');
INSERT INTO "payload_subtypes" VALUES(3,2,'SDR','software-defined radio');
INSERT INTO "payload_subtypes" VALUES(4,3,'microphone array','');
CREATE TABLE payload_types (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    description TEXT NOT NULL DEFAULT ''
) STRICT;
INSERT INTO "payload_types" VALUES(1,'optical','imaging');
INSERT INTO "payload_types" VALUES(2,'radio frequency','');
INSERT INTO "payload_types" VALUES(3,'sound','');
CREATE TABLE payloads (
    id INTEGER PRIMARY KEY CHECK (id >= 1),
    user_id TEXT NOT NULL CHECK (length(user_id) BETWEEN 1 AND 48 AND user_id = trim(user_id)),
    layout_id INTEGER NOT NULL REFERENCES payload_layouts(id),
    CONSTRAINT payload_user_id_layout_unique UNIQUE (user_id, layout_id)
) STRICT;
INSERT INTO "payloads" VALUES(1,'CAM-01',1);
INSERT INTO "payloads" VALUES(2,'CAM-02',1);
INSERT INTO "payloads" VALUES(3,'CAM-03',1);
INSERT INTO "payloads" VALUES(4,'CAM-04',1);
INSERT INTO "payloads" VALUES(5,'CAM-05',1);
INSERT INTO "payloads" VALUES(6,'CAM-06',1);
INSERT INTO "payloads" VALUES(7,'EO12-01',2);
INSERT INTO "payloads" VALUES(8,'EO12-02',2);
INSERT INTO "payloads" VALUES(9,'TH640-01',3);
INSERT INTO "payloads" VALUES(10,'SDR-01',4);
INSERT INTO "payloads" VALUES(11,'SDR-02',4);
INSERT INTO "payloads" VALUES(12,'EO12-03',2);
INSERT INTO "payloads" VALUES(13,'EO12-04',2);
CREATE TABLE pid_controllers (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    p REAL NOT NULL CHECK (p BETWEEN -1e9 AND 1e9),
    i REAL NOT NULL CHECK (i BETWEEN -1e9 AND 1e9),
    d REAL NOT NULL CHECK (d BETWEEN -1e9 AND 1e9),
    max_integral REAL NOT NULL CHECK (max_integral BETWEEN 0 AND 1e9),
    anti_windup INTEGER NOT NULL DEFAULT 1 CHECK (anti_windup IN (0, 1))
) STRICT;
INSERT INTO "pid_controllers" VALUES(1,'gimbal roll',0.8,0.05,0.02,10.0,1);
INSERT INTO "pid_controllers" VALUES(2,'gimbal tilt',0.8,0.05,0.02,10.0,1);
INSERT INTO "pid_controllers" VALUES(3,'gimbal pan',0.6,0.03,0.01,10.0,1);
CREATE TABLE sensor_params (
    sensor_id INTEGER PRIMARY KEY REFERENCES sensors(id) ON DELETE CASCADE,
    hfov_deg REAL CHECK (hfov_deg > 0 AND hfov_deg < 180),
    vfov_deg REAL CHECK (vfov_deg > 0 AND vfov_deg < 180),
    width_px INTEGER CHECK (width_px BETWEEN 1 AND 100000),
    height_px INTEGER CHECK (height_px BETWEEN 1 AND 100000),
    frame_rate_hz REAL CHECK (frame_rate_hz > 0 AND frame_rate_hz <= 100000),
    range_m REAL CHECK (range_m > 0 AND range_m <= 1e7)
) STRICT;
INSERT INTO "sensor_params" VALUES(1,60.0,46.8,1440,1080,30.0,NULL);
INSERT INTO "sensor_params" VALUES(2,72.0,57.2,4000,3000,30.0,NULL);
INSERT INTO "sensor_params" VALUES(3,32.0,25.8,640,512,30.0,NULL);
INSERT INTO "sensor_params" VALUES(4,NULL,NULL,NULL,NULL,NULL,5000.0);
CREATE TABLE sensors (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    kind TEXT NOT NULL CHECK (kind IN ('camera', 'thermal', 'lidar', 'radar', 'sdr', 'microphone', 'other')),
    description TEXT NOT NULL DEFAULT ''
) STRICT;
INSERT INTO "sensors" VALUES(1,'EO 1.5 Mpx','camera','');
INSERT INTO "sensors" VALUES(2,'EO 12 Mpx','camera','');
INSERT INTO "sensors" VALUES(3,'Thermal 640x512','thermal','');
INSERT INTO "sensors" VALUES(4,'SDR 70 MHz-6 GHz','sdr','');
INSERT INTO "sensors" VALUES(5,'8-microphone array','microphone','');
CREATE TABLE system_layouts (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    model_id INTEGER NOT NULL REFERENCES system_models(id),
    payload_layout_id INTEGER REFERENCES payload_layouts(id),
    computer_id INTEGER REFERENCES computer_layouts(id),
    description TEXT NOT NULL DEFAULT ''
) STRICT;
INSERT INTO "system_layouts" VALUES(1,'Albatross 250 VTOL + EO 1.5 Mpx',1,1,2,'');
INSERT INTO "system_layouts" VALUES(2,'Quadcopter + EO 12 Mpx',2,2,1,'');
INSERT INTO "system_layouts" VALUES(3,'Quadcopter + thermal',2,3,1,'');
INSERT INTO "system_layouts" VALUES(4,'Rover + SDR',3,4,1,'');
INSERT INTO "system_layouts" VALUES(5,'Boat + EO 12 Mpx',4,2,1,'');
INSERT INTO "system_layouts" VALUES(6,'Ground station',5,NULL,3,'');
CREATE TABLE system_model_params (
    model_id INTEGER PRIMARY KEY REFERENCES system_models(id) ON DELETE CASCADE,
    cruise_speed_m_s REAL NOT NULL CHECK (cruise_speed_m_s BETWEEN 0 AND 300),
    min_speed_m_s REAL NOT NULL DEFAULT 0 CHECK (min_speed_m_s BETWEEN 0 AND 300),
    max_speed_m_s REAL NOT NULL CHECK (max_speed_m_s BETWEEN 0 AND 300),
    max_bank_deg REAL NOT NULL DEFAULT 45 CHECK (max_bank_deg >= 0 AND max_bank_deg < 90),
    climb_rate_m_s REAL NOT NULL DEFAULT 0 CHECK (climb_rate_m_s BETWEEN 0 AND 100),
    sink_rate_m_s REAL NOT NULL DEFAULT 0 CHECK (sink_rate_m_s BETWEEN 0 AND 100),
    loiter_radius_m REAL NOT NULL DEFAULT 0 CHECK (loiter_radius_m BETWEEN 0 AND 10000),
    has_parachute INTEGER NOT NULL DEFAULT 0 CHECK (has_parachute IN (0, 1)),
    max_altitude_m REAL NOT NULL DEFAULT 0 CHECK (max_altitude_m BETWEEN 0 AND 8000),
    wingspan_m REAL NOT NULL DEFAULT 0 CHECK (wingspan_m BETWEEN 0 AND 100),
    mass_kg REAL NOT NULL DEFAULT 0 CHECK (mass_kg BETWEEN 0 AND 100000),
    CONSTRAINT speeds_ordered CHECK (
        min_speed_m_s <= cruise_speed_m_s AND cruise_speed_m_s <= max_speed_m_s)
) STRICT;
INSERT INTO "system_model_params" VALUES(1,26.0,15.5,32.0,45.0,5.0,5.0,80.0,1,4800.0,2.5,12.5);
INSERT INTO "system_model_params" VALUES(2,10.0,0.0,15.0,30.0,2.5,1.5,10.0,0,3000.0,0.65,2.5);
INSERT INTO "system_model_params" VALUES(3,2.0,0.0,5.0,0.0,0.0,0.0,2.0,0,0.0,0.5,5.0);
INSERT INTO "system_model_params" VALUES(4,2.0,0.0,4.0,0.0,0.0,0.0,2.0,0,0.0,0.6,8.0);
INSERT INTO "system_model_params" VALUES(5,0.0,0.0,0.0,0.0,0.0,0.0,0.0,0,0.0,0.0,0.0);
CREATE TABLE system_models (
    id INTEGER PRIMARY KEY,
    subtype_id INTEGER NOT NULL REFERENCES system_subtypes(id),
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    description TEXT NOT NULL DEFAULT ''
) STRICT;
INSERT INTO "system_models" VALUES(1,2,'Albatross 250 VTOL','the paper''s platform: carbon fibre, 2.5 m span, 12S, MTOW 15 kg');
INSERT INTO "system_models" VALUES(2,3,'Generic Quadcopter','ArduCopter quad X');
INSERT INTO "system_models" VALUES(3,5,'Generic Rover','ArduRover skid-steer');
INSERT INTO "system_models" VALUES(4,6,'Generic Boat','ArduRover boat frame');
INSERT INTO "system_models" VALUES(5,7,'Ground Station','operator laptop running gcs');
CREATE TABLE system_params (
    system_id INTEGER NOT NULL REFERENCES systems(id) ON DELETE CASCADE,
    name TEXT NOT NULL CHECK (length(name) BETWEEN 1 AND 64 AND name = trim(name)),
    value TEXT NOT NULL,
    PRIMARY KEY (system_id, name)
) STRICT;
INSERT INTO "system_params" VALUES(1,'mav_sysid','1');
INSERT INTO "system_params" VALUES(1,'mac_address','02:00:00:00:00:01');
INSERT INTO "system_params" VALUES(2,'mav_sysid','2');
INSERT INTO "system_params" VALUES(2,'mac_address','02:00:00:00:00:02');
INSERT INTO "system_params" VALUES(3,'mav_sysid','3');
INSERT INTO "system_params" VALUES(3,'mac_address','02:00:00:00:00:03');
INSERT INTO "system_params" VALUES(4,'mav_sysid','4');
INSERT INTO "system_params" VALUES(4,'mac_address','02:00:00:00:00:04');
INSERT INTO "system_params" VALUES(5,'mav_sysid','5');
INSERT INTO "system_params" VALUES(5,'mac_address','02:00:00:00:00:05');
INSERT INTO "system_params" VALUES(6,'mav_sysid','6');
INSERT INTO "system_params" VALUES(6,'mac_address','02:00:00:00:00:06');
INSERT INTO "system_params" VALUES(7,'mav_sysid','7');
INSERT INTO "system_params" VALUES(7,'mac_address','02:00:00:00:00:07');
INSERT INTO "system_params" VALUES(8,'mav_sysid','8');
INSERT INTO "system_params" VALUES(8,'mac_address','02:00:00:00:00:08');
INSERT INTO "system_params" VALUES(9,'mav_sysid','9');
INSERT INTO "system_params" VALUES(9,'mac_address','02:00:00:00:00:09');
INSERT INTO "system_params" VALUES(10,'mav_sysid','10');
INSERT INTO "system_params" VALUES(10,'mac_address','02:00:00:00:00:0a');
INSERT INTO "system_params" VALUES(11,'mav_sysid','11');
INSERT INTO "system_params" VALUES(11,'mac_address','02:00:00:00:00:0b');
INSERT INTO "system_params" VALUES(12,'mav_sysid','12');
INSERT INTO "system_params" VALUES(12,'mac_address','02:00:00:00:00:0c');
INSERT INTO "system_params" VALUES(13,'mav_sysid','13');
INSERT INTO "system_params" VALUES(13,'mac_address','02:00:00:00:00:0d');
INSERT INTO "system_params" VALUES(900,'mac_address','02:00:00:00:03:84');
INSERT INTO "system_params" VALUES(1,'udev_rule','SUBSYSTEM=="tty", ATTRS{idVendor}=="0403", ATTRS{idProduct}=="6015", SYMLINK+="xtend"');
INSERT INTO "system_params" VALUES(2,'udev_rule','SUBSYSTEM=="tty", ATTRS{idVendor}=="0403", ATTRS{idProduct}=="6015", SYMLINK+="xtend"');
INSERT INTO "system_params" VALUES(3,'udev_rule','SUBSYSTEM=="tty", ATTRS{idVendor}=="0403", ATTRS{idProduct}=="6015", SYMLINK+="xtend"');
INSERT INTO "system_params" VALUES(4,'udev_rule','SUBSYSTEM=="tty", ATTRS{idVendor}=="0403", ATTRS{idProduct}=="6015", SYMLINK+="xtend"');
INSERT INTO "system_params" VALUES(5,'udev_rule','SUBSYSTEM=="tty", ATTRS{idVendor}=="0403", ATTRS{idProduct}=="6015", SYMLINK+="xtend"');
INSERT INTO "system_params" VALUES(6,'udev_rule','SUBSYSTEM=="tty", ATTRS{idVendor}=="0403", ATTRS{idProduct}=="6015", SYMLINK+="xtend"');
CREATE TABLE system_subtypes (
    id INTEGER PRIMARY KEY,
    type_id INTEGER NOT NULL REFERENCES system_types(id),
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    vehicle_type INTEGER NOT NULL CHECK (vehicle_type BETWEEN 0 AND 255),
    description TEXT NOT NULL DEFAULT ''
) STRICT;
INSERT INTO "system_subtypes" VALUES(1,1,'fixed-wing',1,'');
INSERT INTO "system_subtypes" VALUES(2,1,'VTOL',2,'QuadPlane: vertical take-off, fixed-wing cruise');
INSERT INTO "system_subtypes" VALUES(3,1,'multirotor',3,'');
INSERT INTO "system_subtypes" VALUES(4,1,'helicopter',3,'');
INSERT INTO "system_subtypes" VALUES(5,2,'rover',4,'');
INSERT INTO "system_subtypes" VALUES(6,3,'boat',5,'');
INSERT INTO "system_subtypes" VALUES(7,4,'ground control station',6,'');
CREATE TABLE system_types (
    id INTEGER PRIMARY KEY,
    name TEXT NOT NULL UNIQUE CHECK (length(name) BETWEEN 1 AND 48 AND name = trim(name)),
    description TEXT NOT NULL DEFAULT ''
) STRICT;
INSERT INTO "system_types" VALUES(1,'UAV','unmanned aerial vehicle');
INSERT INTO "system_types" VALUES(2,'UGV','unmanned ground vehicle');
INSERT INTO "system_types" VALUES(3,'USV','unmanned surface vehicle');
INSERT INTO "system_types" VALUES(4,'GCS','ground control station');
CREATE TABLE systems (
    id INTEGER PRIMARY KEY CHECK (id BETWEEN 1 AND 65534),
    user_id TEXT NOT NULL CHECK (length(user_id) BETWEEN 1 AND 48 AND user_id = trim(user_id)),
    layout_id INTEGER NOT NULL REFERENCES system_layouts(id),
    CONSTRAINT system_user_id_layout_unique UNIQUE (user_id, layout_id)
) STRICT;
INSERT INTO "systems" VALUES(1,'ALB-01',1);
INSERT INTO "systems" VALUES(2,'ALB-02',1);
INSERT INTO "systems" VALUES(3,'ALB-03',1);
INSERT INTO "systems" VALUES(4,'ALB-04',1);
INSERT INTO "systems" VALUES(5,'ALB-05',1);
INSERT INTO "systems" VALUES(6,'ALB-06',1);
INSERT INTO "systems" VALUES(7,'QUAD-01',2);
INSERT INTO "systems" VALUES(8,'QUAD-02',2);
INSERT INTO "systems" VALUES(9,'QUAD-03',3);
INSERT INTO "systems" VALUES(10,'ROVER-01',4);
INSERT INTO "systems" VALUES(11,'ROVER-02',4);
INSERT INTO "systems" VALUES(12,'BOAT-01',5);
INSERT INTO "systems" VALUES(13,'BOAT-02',5);
INSERT INTO "systems" VALUES(900,'GCS-01',6);
CREATE TRIGGER gimbal_configs_axis_kind_insert BEFORE INSERT ON gimbal_configs
WHEN EXISTS (SELECT 1 FROM gimbal_axis_params WHERE id = NEW.pan_axis_id AND axis <> 'pan')
  OR EXISTS (SELECT 1 FROM gimbal_axis_params WHERE id = NEW.tilt_axis_id AND axis <> 'tilt')
  OR EXISTS (SELECT 1 FROM gimbal_axis_params WHERE id = NEW.roll_axis_id AND axis <> 'roll')
BEGIN
    SELECT RAISE(ABORT, 'gimbal axis kind: pan_axis, tilt_axis and roll_axis must name a pan, tilt and roll axis');
END;
CREATE TRIGGER gimbal_configs_axis_kind_update
BEFORE UPDATE OF pan_axis_id, tilt_axis_id, roll_axis_id ON gimbal_configs
WHEN EXISTS (SELECT 1 FROM gimbal_axis_params WHERE id = NEW.pan_axis_id AND axis <> 'pan')
  OR EXISTS (SELECT 1 FROM gimbal_axis_params WHERE id = NEW.tilt_axis_id AND axis <> 'tilt')
  OR EXISTS (SELECT 1 FROM gimbal_axis_params WHERE id = NEW.roll_axis_id AND axis <> 'roll')
BEGIN
    SELECT RAISE(ABORT, 'gimbal axis kind: pan_axis, tilt_axis and roll_axis must name a pan, tilt and roll axis');
END;
CREATE TRIGGER gimbal_axis_kind_in_use BEFORE UPDATE OF axis ON gimbal_axis_params
WHEN NEW.axis <> OLD.axis AND EXISTS (
    SELECT 1 FROM gimbal_configs
    WHERE pan_axis_id = OLD.id OR tilt_axis_id = OLD.id OR roll_axis_id = OLD.id)
BEGIN
    SELECT RAISE(ABORT, 'gimbal axis kind: the axis is used by a gimbal configuration');
END;
CREATE INDEX payload_subtypes_type ON payload_subtypes(type_id);
CREATE INDEX payload_models_subtype ON payload_models(subtype_id);
CREATE INDEX payloads_layout ON payloads(layout_id);
CREATE INDEX system_subtypes_type ON system_subtypes(type_id);
CREATE INDEX system_models_subtype ON system_models(subtype_id);
CREATE INDEX system_layouts_model ON system_layouts(model_id);
CREATE INDEX systems_layout ON systems(layout_id);
CREATE INDEX comms_systems_system ON comms_systems(system_id);
COMMIT;
