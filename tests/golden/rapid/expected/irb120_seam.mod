MODULE irb120_seam
  ! Weld seam on the table fixture of an IRB 120: approach, a line, an arc, a line, retract.
  ! Targets are in the work object "table"; the torch is 150 mm long.
  PERS tooldata torch := [TRUE,[[0,0,150],[1,0,0,0]],[1.2,[0,0,60],[1,0,0,0],0,0,0]];
  PERS wobjdata table := [FALSE,TRUE,"",[[300,-150,100],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];
  CONST jointtarget home := [[0,0,0,0,30,0],[9E9,9E9,9E9,9E9,9E9,9E9]];
  CONST robtarget p10 := [[40.1679,59.4692,120.3226],[0.000136059,0.000745307,0.999999624,0.000421563],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];
  CONST robtarget p20 := [[40.1712,59.5226,20.2672],[0.000122343,0.000628356,0.999999729,0.000364720],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];
  CONST robtarget p30 := [[160.4671,59.6099,20.1713],[0.000112477,0.000404664,0.999999838,0.000384425],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];
  CONST robtarget p40 := [[220,120,20],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];
  CONST robtarget p40_1 := [[184.0278,174.9424,20.1540],[0.000048402,0.000371177,0.999999844,0.000414088],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];
  CONST robtarget p50 := [[160.5547,179.6592,20.1794],[0.000045113,0.000420960,0.999999830,0.000400837],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];
  CONST robtarget p60 := [[40.3328,179.5142,20.2733],[0.000036486,0.000646847,0.999999712,0.000395689],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];
  VAR num seams := 0;

  PROC main()
    ConfL \On;
    MoveAbsJ home, v1000, z50, torch;
    MoveJ p10, v1000, z20, torch\WObj:=table;
    MoveL p20, v200, fine, torch\WObj:=table;
    SetDO do_torch, 1;  ! arc on
    MoveL p30, v20, z1, torch\WObj:=table;
    MoveC [[215.8662,96.3118,20.1097],[0.000095191,0.000289973,0.999999859,0.000435630],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]], [[203.7702,161.4470,20.1302],[0.000056526,0.000326756,0.999999853,0.000428853],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]], v20, z1, torch\WObj:=table;
    MoveC p40_1, p50, v20, z1, torch\WObj:=table;
    MoveL p60, v20, fine, torch\WObj:=table;
    SetDO do_torch, 0;  ! arc off
    WaitTime 0.5;
    MoveL [[40.3465,179.4639,120.3256],[0.000029589,0.000766075,0.999999601,0.000459049],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]], v200, z20, torch\WObj:=table;
    seams := seams + 1;
    MoveAbsJ home, v1000, fine, torch;
  ENDPROC
ENDMODULE
