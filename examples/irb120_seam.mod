MODULE irb120_seam
  ! Weld seam on the table fixture of an IRB 120: approach, a line, an arc, a line, retract.
  ! Targets are in the work object "table"; the torch is 150 mm long.
  PERS tooldata torch := [TRUE,[[0,0,150],[1,0,0,0]],[1.2,[0,0,60],[1,0,0,0],0,0,0]];
  PERS wobjdata table := [FALSE,TRUE,"",[[300,-150,100],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];
  CONST jointtarget home := [[0,0,0,0,30,0],[9E9,9E9,9E9,9E9,9E9,9E9]];
  CONST robtarget p10 := [[40,60,120],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];
  CONST robtarget p20 := [[40,60,20],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];
  CONST robtarget p30 := [[160,60,20],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];
  CONST robtarget p40 := [[220,120,20],[0,0,1,0],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];
  CONST robtarget p50 := [[160,180,20],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];
  CONST robtarget p60 := [[40,180,20],[0,0,1,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];
  VAR num seams := 0;

  PROC main()
    ConfL \On;
    MoveAbsJ home, v1000, z50, torch;
    MoveJ p10, v1000, z20, torch\WObj:=table;
    MoveL p20, v200, fine, torch\WObj:=table;
    SetDO do_torch, 1;  ! arc on
    MoveL p30, v20, z1, torch\WObj:=table;
    MoveC p40, p50, v20, z1, torch\WObj:=table;
    MoveL p60, v20, fine, torch\WObj:=table;
    SetDO do_torch, 0;  ! arc off
    WaitTime 0.5;
    MoveL Offs(p60,0,0,100), v200, z20, torch\WObj:=table;
    seams := seams + 1;
    MoveAbsJ home, v1000, fine, torch;
  ENDPROC
ENDMODULE
